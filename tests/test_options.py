"""Options refused in one place: the schema mechanism (``wwcore.options``), the registries' ``choose``, and every
command that takes a scenario, for the three plant kinds. A refusal exits 2, names the key, and writes nothing."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any

import pytest
from pydantic import BaseModel, Field

from service.farm.interfaces import FarmContext
from service.hydro.builtin import HydroContext
from service.plugins import ROLES, TURBINE_DETECTORS, AlgorithmOptionError, Registry, UnknownAlgorithmError, choose
from service.turbine.interfaces import TurbineContext
from windwarden.cli import main
from windwarden.commands.common import with_wake_model
from windwarden.evaluation.random_scenarios import generate
from windwarden.kinds import RunInfo, kind_for
from wwcore.hydro_params import NOMINAL
from wwcore.options import Bounds, OptionSchema
from wwcore.scenario import ScenarioError, load_scenario, parse_scenario, shipped_scenarios
from wwcore.scenario.farm import FarmPlant
from wwcore.scenario.model import SUPERVISOR_ROLES
from wwcore.turbine_params import BENCHMARK

EXAMPLE = Path(__file__).resolve().parents[1] / "docs" / "examples" / "median_voter.py"


@dataclass(frozen=True)
class Settings:
    window: Annotated[int, Bounds(ge=1, le=100, unit="ticks")] = 4
    rate: Annotated[float, Bounds(gt=0.0, le=1000.0, unit="1/1000 s")] = 0.01
    tau: Annotated[tuple[float, float], Bounds(gt=0.0, unit="s")] = (0.1, 0.1)
    pole: Annotated[float | None, Bounds(lt=0.0)] = None
    on: bool = True


@dataclass(frozen=True)
class Extra:
    window: Annotated[int, Bounds(ge=1)] = 10


# -- the schema ----------------------------------------------------------------------------------------------------
def test_a_schema_is_read_from_the_dataclass_fields():
    schema = OptionSchema({"": Settings, "extra_": Extra})
    assert schema.keys() == ["window", "rate", "tau", "pole", "on", "extra_window"]
    assert schema.options["rate"].bounds == Bounds(gt=0.0, le=1000.0, unit="1/1000 s")
    assert schema.options["tau"].default == (0.1, 0.1)
    values, problems = schema.validate({"window": 5, "tau": [0.05, 0.2], "extra_window": 3, "on": False, "x": 1})
    assert problems == [] and values == {"window": 5, "tau": (0.05, 0.2), "extra_window": 3, "on": False}
    assert schema.validate({"rate": 2})[0] == {"rate": 2.0}  # an integer is a number


@pytest.mark.parametrize(
    ("params", "key", "words"),
    [
        ({"window": 0}, "window", "greater than or equal to 1"),
        ({"window": 101}, "window", "less than or equal to 100"),
        ({"window": 4.5}, "window", "integer"),
        ({"rate": 0.0}, "rate", "greater than 0"),
        ({"rate": "0.1"}, "rate", "number"),
        ({"tau": [0.1, -0.1]}, "tau[1]", "greater than 0"),
        ({"tau": [0.1]}, "tau[1]", "required"),
        ({"pole": 1.0}, "pole", "less than 0"),
        ({"on": 1}, "on", "boolean"),
        ({"extra_window": 0}, "extra_window", "greater than or equal to 1"),
    ],
)
def test_a_schema_refuses_wrong_types_and_values_out_of_range(params, key, words):
    values, problems = OptionSchema({"": Settings, "extra_": Extra}).validate(params)
    assert values == {}
    [(where, message)] = problems
    assert where == key and words in message


def test_a_pydantic_model_declares_options_too_and_a_key_cannot_be_declared_twice():
    class Model(BaseModel):
        gain: float = Field(default=1.0, gt=0.0)

    schema = OptionSchema.of(Model)
    assert schema.validate({"gain": 2.0}) == ({"gain": 2.0}, [])
    assert schema.validate({"gain": -1.0})[1][0][0] == "gain"
    with pytest.raises(TypeError, match="declared twice"):
        OptionSchema({"": Settings, "win": dataclasses.make_dataclass("D", [("dow", int, 1)])})


# -- the registries ------------------------------------------------------------------------------------------------
def test_the_kinds_roles_agree_between_the_scenario_and_the_registries():
    assert {kind: tuple(roles) for kind, roles in ROLES.items()} == SUPERVISOR_ROLES


def _numeric(hint: Any) -> bool:
    text = str(hint)
    return "int" in text or "float" in text


def test_every_numeric_option_of_every_built_in_algorithm_declares_its_range():
    """A field added to a settings dataclass is an option at once; it must say its range where it is declared."""
    for roles in ROLES.values():
        for registry in roles.values():
            for name in registry.names():
                for info in registry.options(name).options.values():
                    if info.type_text != "bool" and "Literal" not in info.type_text:
                        assert info.bounds is not None, f"{registry.role} {name!r}: {info.key} has no Bounds"


class Recording(dict):
    """Options that remember every key an algorithm asks for."""

    def __init__(self):
        super().__init__()
        self.asked: set[str] = set()

    def get(self, key, default=None):
        self.asked.add(key)
        return super().get(key, default)

    def __getitem__(self, key):
        self.asked.add(key)
        return super().__getitem__(key)

    def __contains__(self, key):
        self.asked.add(key)
        return super().__contains__(key)


def test_every_key_a_built_in_algorithm_reads_is_declared():
    contexts = {"turbine": TurbineContext(BENCHMARK, 1, "sigma"), "farm": FarmContext(FarmPlant().site(), 9)}
    for kind in ("turbine", "farm"):
        for registry in ROLES[kind].values():
            for name in registry.names():
                if name not in BUILT_IN[kind]:
                    continue
                options = Recording()
                registry.create(name, options=options, context=contexts[kind])
                assert options.asked <= set(registry.options(name).options), f"{registry.role} {name!r}"
    for name in ("threshold", "none"):
        options = Recording()
        ROLES["hydro"]["detector"].create(name, context=HydroContext(1, NOMINAL, "ts-smo"), options=options)
        assert options.asked <= set(ROLES["hydro"]["detector"].options(name).options)


BUILT_IN = {"turbine": {"benchmark", "uio-bank", "none"}, "farm": {"paper", "analytic", "dispatch", "pi", "none"}}


def test_choose_refuses_every_bad_key_at_once_and_names_it():
    with pytest.raises(AlgorithmOptionError) as caught:
        choose("farm", {"trim_kpp": 0.1, "trim_limit": 2.0, "accommodation_rule": "magic"}, estimator="uio-bank")
    keys = [key for key, _ in caught.value.problems]
    assert keys == [
        "supervisor.estimator",
        "supervisor.params.trim_kpp",
        "supervisor.params.accommodation_rule",
        "supervisor.params.trim_limit",
    ]
    assert "did you mean 'trim_kp'" in str(caught.value)
    with pytest.raises(UnknownAlgorithmError, match="no hydro detector named 'magic'"):
        choose("hydro", {}, detector="magic")


def test_each_algorithm_receives_the_keys_it_declared():
    choice = choose("turbine", {"window": 5, "component_block": 20, "warmup_s": 3.0, "wind_every": 10})
    assert choice.names == {"detector": "benchmark", "estimator": "uio-bank"}
    assert choice.options["detector"] == {"window": 5, "component_block": 20, "warmup_s": 3.0}
    assert choice.options["estimator"] == {"warmup_s": 3.0, "wind_every": 10}


def test_a_plug_in_that_declares_nothing_works_and_gets_no_options(monkeypatch):
    registry: Registry[Any] = Registry("test detector", "for this test", default="quiet")
    received = []

    @registry.register("quiet")
    class Quiet:
        def __init__(self, *, options):
            received.append(options)

    monkeypatch.setitem(ROLES, "test", {"detector": registry})
    registry.create("quiet", options=choose("test", {}).options["detector"])
    assert received == [{}]
    with pytest.raises(AlgorithmOptionError, match=r"supervisor\.params\.window: unknown option"):
        choose("test", {"window": 4})


def test_the_supervisors_refuse_bad_options_before_building_anything():
    from service.hydro.supervisor import HydroSupervisor

    with pytest.raises(AlgorithmOptionError, match=r"supervisor\.params\.tau_filtr"):
        HydroSupervisor(n=1, options={"tau_filtr": [0.05, 0.05]})
    with pytest.raises(AlgorithmOptionError, match=r"supervisor.params.tau_filter\[0\]"):
        HydroSupervisor(n=1, options={"tau_filter": [-0.05, 0.05]})


@pytest.mark.parametrize("kind", ["turbine", "farm", "hydro"])
def test_the_live_supervisor_refuses_a_runs_bad_options(kind):
    """``windwarden supervise`` builds from the plant's run description: the same check, the same message."""
    plant = {"turbine": {"kind": "turbine"}, "farm": {"kind": "farm"}, "hydro": {"kind": "hydro"}}[kind]
    scenario = parse_scenario({"name": "s", "duration_s": 10.0, "plant": plant})
    info = RunInfo.of(scenario, [1], 0.01)
    info = info.model_copy(update={"supervisor": info.supervisor.model_copy(update={"params": {"no_such_option": 1}})})
    with pytest.raises(AlgorithmOptionError, match=r"supervisor\.params\.no_such_option"):
        kind_for(kind).make_supervisor(info)


# -- the commands --------------------------------------------------------------------------------------------------
PLANTS = {
    "turbine": '[plant]\nkind = "turbine"\n[wind]\nmean = [[0.0, 10.0]]\n',
    "farm": '[plant]\nkind = "farm"\n',
    "hydro": '[plant]\nkind = "hydro"\n[wind]\nmean = [[0.0, 7.5]]\n',
}
BAD_PARAMS = {
    # kind: (an unknown key, a value out of range), each as a [supervisor.params] line and the key to name
    "turbine": (("windo = 4", "windo"), ("false_alarms_per_1000s = -1.0", "false_alarms_per_1000s")),
    "farm": (("trim_kpp = 0.1", "trim_kpp"), ("trim_limit = 2.0", "trim_limit")),
    "hydro": (("tau_filtr = [0.05, 0.05]", "tau_filtr"), ("tau_filter = [0.05, -1.0]", "tau_filter[1]")),
}
UNUSED_FLAGS = {
    "turbine": (
        ["--no-compensation"],
        ["--controller", "pi"],
        ["--compare"],
        ["--no-accommodation"],
        ["--wake-model", "rows"],
    ),
    "farm": (["--no-compensation"], ["--estimator", "uio-bank"]),
    "hydro": (["--controller", "pi"], ["--no-accommodation"], ["--no-twins"], ["--compare"], ["--wake-model", "gauss"]),
}


def _scenario(tmp_path: Path, kind: str, params: str = "") -> Path:
    path = tmp_path / f"{kind}.toml"
    text = f'name = "{kind}-options"\nduration_s = 10.0\n' + PLANTS[kind]
    path.write_text(text + (f"[supervisor.params]\n{params}\n" if params else ""))
    return path


def _refused(capsys, argv: list[str], *names: str) -> None:
    assert main(argv) == 2
    err = capsys.readouterr().err
    for name in names:
        assert name in err, err


@pytest.mark.parametrize("kind", ["turbine", "farm", "hydro"])
def test_eval_refuses_an_unknown_key_and_a_value_out_of_range(tmp_path, capsys, kind):
    out = tmp_path / "out"
    for line, key in BAD_PARAMS[kind]:
        path = _scenario(tmp_path, kind, line)
        _refused(capsys, ["eval", str(path), "--runs", "1", "--quiet", "--out", str(out)], f"supervisor.params.{key}")
    assert not out.exists()


@pytest.mark.parametrize("kind", ["turbine", "farm", "hydro"])
def test_eval_refuses_a_flag_the_kind_does_not_use(tmp_path, capsys, kind):
    out = tmp_path / "out"
    path = _scenario(tmp_path, kind)
    for flags in UNUSED_FLAGS[kind]:
        _refused(capsys, ["eval", str(path), "--runs", "1", "--quiet", "--out", str(out), *flags], flags[0])
    assert not out.exists()


def test_wake_model_swaps_the_farms_wakes_and_nothing_else():
    shipped = load_scenario("farm-case1")
    rows = with_wake_model(shipped, "rows")
    assert shipped.plant.wake_model == "gauss" and rows.plant.wake_model == "rows"
    assert rows.plant.model_copy(update={"wake_model": "gauss"}) == shipped.plant
    assert (rows.wind, rows.faults, rows.supervisor, rows.duration_s) == (
        shipped.wind,
        shipped.faults,
        shipped.supervisor,
        shipped.duration_s,
    )
    # a random farm set draws its farms on the base with those wakes (eval random:farm --wake-model rows)
    drawn = generate("farm", 3, base=with_wake_model(load_scenario("farm-fault-free-case1"), "rows"))
    assert drawn.plant.wake_model == "rows" and generate("farm", 3).plant.wake_model == "gauss"


def test_eval_refuses_a_wake_model_the_farm_cannot_have(tmp_path, capsys):
    """The row model knows the paper's 3 × 3 only: Horns Rev 1 with --wake-model rows is refused before it runs."""
    out = tmp_path / "out"
    argv = ["eval", "farm-hornsrev1", "--runs", "1", "--quiet", "--out", str(out), "--wake-model", "rows"]
    _refused(capsys, argv, "--wake-model", "layout", "row model")
    _refused(capsys, ["eval", "random:hydro", "--runs", "1", "--quiet", "--wake-model", "rows"], "--wake-model")
    with pytest.raises(SystemExit) as refused:
        main(["eval", "farm-case1", "--runs", "1", "--quiet", "--out", str(out), "--wake-model", "park"])
    assert refused.value.code == 2 and "park" in capsys.readouterr().err
    assert not out.exists()


def test_eval_refuses_options_an_algorithm_finds_inconsistent(tmp_path, capsys):
    """A check across two options lives in the algorithm; eval builds the supervisor once before running."""
    out = tmp_path / "out"
    path = _scenario(tmp_path, "turbine", "window = 3\nclear_window = 4")
    _refused(capsys, ["eval", str(path), "--runs", "1", "--quiet", "--out", str(out)], "clear_window")
    assert not out.exists()


@pytest.mark.parametrize("name", sorted(shipped_scenarios()))
def test_every_shipped_scenario_passes_the_check(name):
    scenario = load_scenario(name)
    spec = scenario.supervisor
    choose(
        scenario.plant.kind, spec.params, detector=spec.detector, estimator=spec.estimator, controller=spec.controller
    )


def test_a_role_the_kind_does_not_have_is_refused_at_load():
    data = {"name": "h", "duration_s": 10.0, "plant": {"kind": "hydro"}, "supervisor": {"controller": "pi"}}
    with pytest.raises(ScenarioError, match=r"supervisor.controller: a hydro supervisor has no controller"):
        parse_scenario(data)
    data = {"name": "f", "duration_s": 10.0, "plant": {"kind": "farm"}, "supervisor": {"estimator": "uio-bank"}}
    with pytest.raises(ScenarioError, match=r"supervisor\.estimator"):
        parse_scenario(data)


@pytest.mark.parametrize("kind", ["turbine", "farm", "hydro"])
def test_up_and_plant_refuse_bad_options_before_anything_runs(tmp_path, capsys, kind):
    runs = tmp_path / "runs"
    for line, key in BAD_PARAMS[kind]:
        path = _scenario(tmp_path, kind, line)
        _refused(capsys, ["up", str(path), "--runs-root", str(runs), "--no-api", "--quiet"], key)
        _refused(capsys, ["plant", str(path), "--runs-root", str(runs), "--connect", "tcp/127.0.0.1:1"], key)
    assert not runs.exists()


def test_the_worked_example_declares_its_option(tmp_path, capsys):
    out = tmp_path / "out"
    path = _scenario(tmp_path, "turbine", "window = 4")  # the bank's option, not the voter's nor the estimator's
    argv = ["eval", str(path), "--runs", "1", "--quiet", "--out", str(out), "--plugin", str(EXAMPLE)]
    _refused(capsys, [*argv, "--detector", "median-voter"], "supervisor.params.window")
    path = _scenario(tmp_path, "turbine", "false_alarms_per_1000s = 0.0")
    _refused(capsys, [*argv, "--detector", "median-voter"], "supervisor.params.false_alarms_per_1000s")
    assert not out.exists()
    assert "median-voter" in TURBINE_DETECTORS.names()
    assert choose("turbine", {"false_alarms_per_1000s": 0.5}, detector="median-voter").options["detector"] == {
        "false_alarms_per_1000s": 0.5
    }
