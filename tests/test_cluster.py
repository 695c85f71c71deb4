"""``eval --scheduler``: the chunks run on a Dask cluster and the scorecard is the local one bit for bit."""

from __future__ import annotations

import json
import sys
import tomllib
from pathlib import Path
from typing import ClassVar

import pytest
from distributed import LocalCluster

from tests.live.helpers import TURBINE_SHORT
from windwarden.cli import main
from windwarden.evaluation import cluster, parallel
from windwarden.evaluation.kinds import EvalOptions
from windwarden.evaluation.usage import ResourceMonitor
from windwarden.kinds import kind_for
from windwarden.live.router import free_port
from wwcore.scenario import parse_scenario

SEED = 9090  # fresh: no figure is tuned on it
EXAMPLE_PLUGIN = Path(__file__).resolve().parents[1] / "docs" / "examples" / "median_voter.py"


@pytest.fixture(scope="module")
def two_workers():
    """Two single-thread worker processes, as `docs/cluster.md` starts them (`--nthreads 1`, one process per core),
    over TCP on loopback: the tasks and their results travel through the scheduler serialised, as they would to
    another machine. Not threads of this process: chunks running side by side in threads of one interpreter are not
    a supported set-up (once, under a loaded `pytest -n 2`, two such threads building supervisors and the main
    thread's garbage collection waited on each other for good)."""
    with LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, protocol="tcp://", host="127.0.0.1", dashboard_address=None
    ) as local:
        yield local.scheduler_address


def test_the_cluster_scorecard_is_the_local_one_bit_for_bit(two_workers):
    scenario = parse_scenario(tomllib.loads(TURBINE_SHORT))
    evaluate = kind_for(scenario.plant.kind).evaluate
    local = evaluate(scenario, 3, SEED, EvalOptions(workers=1, progress=False))
    with ResourceMonitor() as usage:
        remote = evaluate(scenario, 3, SEED, EvalOptions(scheduler=two_workers, progress=False))
    assert json.dumps(remote.scorecard, sort_keys=True) == json.dumps(local.scorecard, sort_keys=True)
    assert local.scorecard["false_alarms_twin"]["observed_s"] > 0  # the twins ran (in-process copies there)
    report = usage.report()["cluster"]
    assert 1 <= report["workers_used"] <= 2 and report["worker_peak_rss_bytes"] > 0


def test_an_unreachable_scheduler_is_refused_and_writes_nothing(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(cluster, "CONNECT_TIMEOUT_S", 1.0)
    scenario = tmp_path / "short.toml"
    scenario.write_text(TURBINE_SHORT)
    out = tmp_path / "out"
    address = f"tcp://127.0.0.1:{free_port()}"  # nothing listens there
    code = main(["eval", str(scenario), "--runs", "2", "--scheduler", address, "--quiet", "--out", str(out)])
    assert code == 2
    assert f"--scheduler: cannot reach the Dask scheduler at {address}" in capsys.readouterr().err
    assert not out.exists()


def test_workers_and_a_scheduler_together_are_refused(tmp_path, capsys):
    scenario = tmp_path / "short.toml"
    scenario.write_text(TURBINE_SHORT)
    code = main(["eval", str(scenario), "--runs", "2", "--workers", "2", "--scheduler", "tcp://127.0.0.1:1"])
    assert code == 2 and "--workers" in capsys.readouterr().err


class RecordingBar:
    """Stands in for tqdm: keeps the bar's total and every update."""

    made: ClassVar[list[RecordingBar]] = []

    def __init__(self, total: float, **_: object):
        self.total, self.updates = total, []
        RecordingBar.made.append(self)

    def update(self, n: float) -> None:
        self.updates.append(n)

    def close(self) -> None:
        pass


def test_a_plugin_file_runs_on_the_cluster_and_the_bar_follows_the_tasks(two_workers, tmp_path, monkeypatch):
    monkeypatch.setattr(parallel, "tqdm", RecordingBar)
    scenario = tmp_path / "short.toml"
    scenario.write_text(TURBINE_SHORT)
    out = tmp_path / "out"
    argv = ["eval", str(scenario), "--runs", "2", "--seed", str(SEED), "--quiet", "--no-plots", "--out", str(out)]
    argv += ["--plugin", str(EXAMPLE_PLUGIN), "--detector", "median-voter", "--scheduler", two_workers]
    assert main(argv) == 0
    assert json.loads((out / "scorecard.json").read_text())["detector"] == "median-voter"
    execution = json.loads((out / "execution.json").read_text())
    assert execution["backend"] == "dask" and execution["scheduler"] == two_workers
    assert execution["environment"]["code"] and execution["cluster"]["workers_used"] >= 1
    [bar] = RecordingBar.made
    assert bar.total == pytest.approx(2 * 30.0) and sum(bar.updates) == pytest.approx(bar.total)
    assert len([n for n in bar.updates if n > 0]) > 2  # the workers' reports, not only the two chunks' ends


def test_a_plugin_file_travels_by_its_source_and_another_version_is_refused(tmp_path):
    plugin = tmp_path / "tiny_probe.py"
    plugin.write_text("VALUE = 1\n")
    try:
        cluster.PluginSet.of([str(plugin)]).load(tmp_path / "worker")
        loaded = sys.modules["windwarden_plugin_tiny_probe"]
        assert loaded.VALUE == 1 and Path(loaded.__file__).parent.parent == tmp_path / "worker"
        cluster.PluginSet.of([str(plugin)]).load(tmp_path / "worker")  # the same source: nothing to do
        plugin.write_text("VALUE = 2\n")
        with pytest.raises(cluster.ClusterError, match=r"another version of the plug-in tiny_probe\.py"):
            cluster.PluginSet.of([str(plugin)]).load(tmp_path / "worker")
        assert loaded.VALUE == 1
    finally:
        sys.modules.pop("windwarden_plugin_tiny_probe", None)
