"""Rewrite the generated blocks of ``docs/detectability.md`` (between ``<!-- name ... -->`` and ``<!-- /name -->``).

    .venv/bin/python tools/detectability_docs.py                        # the tables generated from the code
    .venv/bin/python tools/detectability_docs.py --sweeps A.json B.json  # and the measured curves (plots drawn
                                                                         # into docs/img/detectability/)
    .venv/bin/python tools/detectability_docs.py --random SET1/scorecard.json SET2/scorecard.json

``tests/test_detectability.py`` holds the code-generated blocks to the code.
"""

from __future__ import annotations

import argparse
import json
import re
from pathlib import Path

from windwarden.evaluation.detectability import timing_table
from windwarden.evaluation.detectability_report import markdown, plot
from windwarden.evaluation.fault_types import FAULT_TYPES, catalogue_table
from windwarden.evaluation.random_scenarios import distribution_table
from windwarden.evaluation.random_summary import markdown as random_markdown

DOC = Path(__file__).resolve().parent.parent / "docs" / "detectability.md"
IMAGES = "img/detectability"


def code_blocks() -> dict[str, str]:
    return {"catalogue": catalogue_table(), "timing": timing_table(), "distributions": distribution_table()}


def replace_block(text: str, name: str, body: str) -> str:
    pattern = re.compile(rf"(<!-- {name}(?::[^>]*)? -->\n).*?(<!-- /{name} -->)", re.S)
    if not pattern.search(text):
        raise SystemExit(f"no block {name!r} in {DOC}")
    return pattern.sub(lambda m: m.group(1) + body.strip() + "\n" + m.group(2), text)


def sweep_block(paths: list[Path]) -> str:
    """The measured curves of the sweeps' ``detectability.json`` files, in catalogue order, their plots drawn
    again into docs/img/detectability/."""
    results = [r for p in paths for r in json.loads(p.read_text())]
    order = [t.name for t in FAULT_TYPES]
    results.sort(key=lambda r: order.index(r["fault_type"]))
    images = {}
    for r in results:
        plot(r, DOC.parent / IMAGES / f"{r['fault_type']}.png")
        images[r["fault_type"]] = f"{IMAGES}/{r['fault_type']}.png"
    text = markdown(results, images)
    return text.split("\n", 2)[2].replace("\n### ", "\n#### ")  # without the page title, one level down


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sweeps", type=Path, nargs="*", default=[])
    parser.add_argument("--random", type=Path, nargs="*", default=[])
    args = parser.parse_args()
    text = DOC.read_text()
    for name, body in code_blocks().items():
        text = replace_block(text, name, body)
    if args.sweeps:
        text = replace_block(text, "results", sweep_block(args.sweeps))
    if args.random:
        cards = [json.loads(p.read_text()) for p in args.random]
        text = replace_block(text, "random", "\n".join(random_markdown(c) for c in cards))
    DOC.write_text(text)


if __name__ == "__main__":
    main()
