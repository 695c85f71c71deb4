"""The farm map of the live dashboard: states from the references' flags and modes, the wind arrow's geometry,
north drawn up, and what each process writes into the recording."""

from __future__ import annotations

import numpy as np
import pytest

from dashboards.farm_map import (
    STATES,
    FarmGeometry,
    MapColours,
    geometry_of,
    screen_xy,
    turbine_states,
    wind_arrow,
)
from dashboards.live import LiveRecording
from windwarden.live.finalize import recording_entities
from wwcore.scenario import load_scenario
from wwcore.wire import FARM_REFS

pytestmark = pytest.mark.in_process  # no network, no process: the parallel phase (tests/conftest.py)

D = 115.0


def _refs(n: int, flags: dict[int, int] | None = None, modes: dict[int, int] | None = None) -> np.ndarray:
    refs = np.zeros(n, dtype=FARM_REFS.dtype)
    refs["turbine"] = np.arange(1, n + 1)
    for turbine, kind in (flags or {}).items():
        refs["flags"][turbine - 1, kind] = True
    for turbine, mode in (modes or {}).items():
        refs["mode"][turbine - 1] = mode
    return refs


def _names(state: np.ndarray) -> list[str]:
    return [STATES[i] for i in state]


def test_states_follow_the_flags_and_the_accommodation_modes():
    refs = _refs(6, flags={2: 0, 3: 1, 4: 2}, modes={3: 2, 4: 5, 5: 3, 6: 4})
    state = turbine_states(refs["turbine"], refs["flags"], refs["mode"], 6)
    assert _names(state) == ["healthy", "flagged", "derated", "flagged", "derated", "accommodated"]


def test_rows_in_any_order_and_turbines_without_a_row():
    refs = _refs(4, flags={1: 0})[::-1][:3]  # turbines 4, 3, 2: turbine 1's row is missing
    refs["flags"][2, 1] = True  # turbine 2
    state = turbine_states(refs["turbine"], refs["flags"], refs["mode"], 5)
    assert _names(state) == ["healthy", "flagged", "healthy", "healthy", "healthy"]


def test_north_is_drawn_up():
    xy = screen_xy(np.array([0.0, 100.0]), np.array([0.0, 500.0]))
    assert xy.tolist() == [[0.0, 0.0], [100.0, -500.0]]  # the view's y axis points down the screen


@pytest.mark.parametrize(
    ("wind_from", "toward_screen"),
    [(270.0, (1.0, 0.0)), (90.0, (-1.0, 0.0)), (0.0, (0.0, 1.0)), (180.0, (0.0, -1.0))],
)
def test_the_wind_arrow_points_where_the_air_goes_and_starts_upwind(wind_from, toward_screen):
    east = np.array([0.0, 500.0, 1000.0, 0.0])
    north = np.array([0.0, 0.0, 0.0, 800.0])
    origin, vector = wind_arrow(FarmGeometry(east, north, D, wind_from))
    unit = vector / np.linalg.norm(vector)
    np.testing.assert_allclose(unit, toward_screen, atol=1e-12)
    depth = screen_xy(east, north) @ unit
    assert origin @ unit == pytest.approx(depth.min() - D)  # one rotor diameter upwind of the first turbine
    assert np.linalg.norm(vector) == pytest.approx(max(depth.max() - depth.min(), 3 * D))


def test_the_map_of_the_paper_farm_is_its_three_by_three_grid():
    plant = load_scenario("farm-case1").plant
    geometry = geometry_of(plant)
    assert len(geometry.east_m) == 9 and geometry.wind_from_deg == plant.direction_deg
    assert len(set(np.round(geometry.east_m, 6))) == 3 and len(set(np.round(geometry.north_m, 6))) == 3


def test_an_empty_or_ragged_map_is_refused():
    with pytest.raises(ValueError, match="one entry per turbine"):
        FarmGeometry(np.array([]), np.array([]), D, 270.0)
    with pytest.raises(ValueError, match="one entry per turbine"):
        FarmGeometry(np.array([0.0, 1.0]), np.array([0.0]), D, 270.0)


def test_colours_are_sent_only_when_a_state_changes(tmp_path):
    recording = LiveRecording("farm", "supervisor", "map", path=str(tmp_path / "s.rrd"), n_turbines=3)
    colours = recording.map_colours
    assert isinstance(colours, MapColours)
    healthy, flagged = _refs(3), _refs(3, flags={2: 1})
    sent = [colours.update(recording.rec, "sim_time", t, refs) for t, refs in enumerate([healthy] * 3 + [flagged] * 2)]
    assert sent == [True, False, False, True, False]
    recording.close()
    assert "/farm/map/turbines" in recording_entities(tmp_path / "s.rrd")


def test_the_plant_draws_the_layout_and_the_wind_and_the_supervisor_the_states(tmp_path):
    scenario = load_scenario("farm-case1")
    plant = LiveRecording(
        "farm", "plant", "map", path=str(tmp_path / "p.rrd"), n_turbines=9, plant_section=scenario.plant
    )
    plant.close()
    supervisor = LiveRecording("farm", "supervisor", "map", path=str(tmp_path / "s.rrd"), n_turbines=9)
    supervisor.supervisor_rows(np.zeros(0, dtype=[("t", "<f8")]), _refs(0), [])  # nothing yet: nothing drawn
    assert supervisor.map_colours is not None and supervisor.map_colours.changes == 0
    supervisor.close()
    assert {"/farm/map/turbines", "/farm/map/wind"} <= recording_entities(tmp_path / "p.rrd")
    assert "/farm/map/turbines" not in recording_entities(tmp_path / "s.rrd")


def test_a_single_turbine_or_hydro_run_has_no_map(tmp_path):
    for kind in ("turbine", "hydro"):
        recording = LiveRecording(kind, "supervisor", "m", path=str(tmp_path / f"{kind}.rrd"))
        assert recording.map_colours is None
        recording.close()


def test_a_moving_wind_is_drawn_from_the_vane_on_the_timeline(tmp_path):
    scenario = load_scenario("farm-3x3-veer")
    assert scenario.plant.direction_varies
    plant = LiveRecording(
        "farm", "plant", "veer", path=str(tmp_path / "p.rrd"), n_turbines=9, plant_section=scenario.plant
    )
    arrow = plant.wind_arrow
    assert arrow is not None and arrow.geometry.wind_moves
    frames = np.zeros(9, dtype=[("t", "<f8"), ("turbine", "<i8"), ("mast_direction", "<f8")])
    rng = np.random.default_rng(4)
    draws = []
    for k in range(6000):  # 600 s at 10 Hz: 270° ± 5° vane noise for 300 s, then a turn to 290°
        frames["t"] = 0.1 * k
        frames["mast_direction"] = (270.0 if k < 3000 else 290.0) + 5.0 * rng.standard_normal()
        if arrow.update(plant.rec, "time", 0.1 * k, float(frames["mast_direction"][0])):
            draws.append((0.1 * k, arrow.drawn_deg))
    plant.close()
    assert draws[0][0] == 0.0  # drawn at the first reading
    steady = [d for t, d in draws if 60.0 < t < 300.0]
    assert len(steady) <= 2  # 5° noise on a 60-s mean does not redraw it (σ of the mean ≈ 0.3°)
    assert abs(draws[-1][1] - 290.0) < 2.5 and len(draws) >= 5  # it follows the turn, in steps of ≥ 2°
    assert "/farm/map/wind" in recording_entities(tmp_path / "p.rrd")


def test_a_fixed_wind_has_no_moving_arrow(tmp_path):
    plant = LiveRecording(
        "farm",
        "plant",
        "m",
        path=str(tmp_path / "p.rrd"),
        n_turbines=9,
        plant_section=load_scenario("farm-case1").plant,
    )
    assert plant.wind_arrow is None
    plant.close()
