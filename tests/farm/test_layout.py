"""Farm layouts (wwcore.layout): the shipped files, grids, coordinates, refusals, and the geometry in the wind."""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pydantic import TypeAdapter, ValidationError

from wwcore.layout import (
    HORNS_REV_1,
    MAX_TURBINES,
    SEED001_DIRECTIONS_DEG,
    SEED001_LAYOUT,
    CoordinateLayout,
    FarmLayout,
    FileLayout,
    GridLayout,
    LayoutSpec,
    available_layouts,
)
from wwcore.scenario.farm import FarmPlant

D = 115.0
SPEC = TypeAdapter(LayoutSpec)
REPO_ROOT = Path(__file__).resolve().parents[2]


def _reference_dir() -> Path:
    env = os.environ.get("WINDWARDEN_REFERENCE_DATA")
    return Path(env) if env else REPO_ROOT.parent / "shared" / "data"


def numbers(groups):
    return [tuple(i + 1 for i in g) for g in groups]


def test_shipped_layouts():
    assert {"hornsrev1", "seed001_3x3"} <= set(available_layouts())


@pytest.mark.parametrize("case", [1, 2])
def test_seed001_rows_are_the_papers(case):
    """The 3 × 3 file at the paper's two directions gives the paper's rows and row distances (PARAMETERS.md b)."""
    layout = SEED001_LAYOUT.resolve(D)
    direction = SEED001_DIRECTIONS_DEG[case]
    groups = layout.groups_along_wind(direction, tolerance_m=1.0)
    plant = FarmPlant(wind_case=case)
    assert numbers(groups) == [tuple(sorted(r)) for r in plant.rows()]
    s = layout.wind_frame(direction).downwind
    assert [s[g[0]] for g in groups] == pytest.approx(plant.row_distances_m(), abs=1e-6)
    expected = [(1, 4, 7), (2, 5, 8), (3, 6, 9)] if case == 1 else [(1,), (2, 4), (3, 5, 7), (6, 8), (9,)]
    assert numbers(groups) == expected


def test_grid_equals_the_3x3_file_and_rotates():
    grid = GridLayout(rows=3, columns=3).resolve(D)
    file = SEED001_LAYOUT.resolve(D)
    assert np.allclose(grid.x, file.x) and np.allclose(grid.y, file.y)
    north = GridLayout(rows=2, columns=3, orientation_deg=0.0, column_spacing_d=5.0, row_spacing_d=4.0).resolve(D)
    # rows run north, the second row stands to their right (east)
    assert north.x.tolist() == pytest.approx([0, 0, 0, 4 * D, 4 * D, 4 * D])
    assert north.y.tolist() == pytest.approx([0, 5 * D, 10 * D, 0, 5 * D, 10 * D])


def test_horns_rev_is_scaled_by_rotor_diameter():
    layout = HORNS_REV_1.resolve(D)
    assert layout.n_turbines == 80
    assert 6.9 < layout.spacing_d() < 7.1  # 7 D of the benchmark rotor, as 7 D of the V80 in the source
    # turbines 1, 8 and 80 of the source (UTM 32N easting/northing, V80 D = 80 m)
    src = {1: (423974.0, 6151447.0), 8: (424452.0, 6147556.0), 80: (429492.0, 6147556.0)}
    for k, (e, n) in src.items():
        assert layout.x[k - 1] == pytest.approx((e - 423974.0) * D / 80.0)
        assert layout.y[k - 1] == pytest.approx((n - 6151447.0) * D / 80.0)
    unscaled = FileLayout(name="hornsrev1", scale_to_rotor=False).resolve(D)
    assert unscaled.x[-1] == pytest.approx(429492.0 - 423974.0)


def test_horns_rev_matches_the_source_file():
    source = _reference_dir() / "hornsrev1_layout.csv"
    if not source.is_file():
        pytest.skip(f"{source} not found (set WINDWARDEN_REFERENCE_DATA)")
    rows = [line.split(",") for line in source.read_text().splitlines() if line and line[0].isdigit()]
    e = np.array([float(r[1]) for r in rows])
    n = np.array([float(r[2]) for r in rows])
    layout = HORNS_REV_1.resolve(D)
    assert np.array_equal(np.array([int(r[0]) for r in rows]), np.arange(1, 81))
    assert np.allclose(layout.x, (e - e[0]) * D / 80.0, atol=1e-9)
    assert np.allclose(layout.y, (n - n[0]) * D / 80.0, atol=1e-9)


def test_one_and_150_turbines_are_accepted():
    assert SPEC.validate_python({"kind": "coordinates", "x_m": [0.0], "y_m": [0.0]}).resolve(D).n_turbines == 1
    big = SPEC.validate_python({"kind": "grid", "rows": 10, "columns": 15, "column_spacing_d": 5.0})
    assert big.resolve(D).n_turbines == 150
    assert FarmLayout(np.arange(MAX_TURBINES) * 2 * D, np.zeros(MAX_TURBINES), D).n_turbines == MAX_TURBINES


@pytest.mark.parametrize(
    ("data", "message"),
    [
        ({"kind": "coordinates", "x_m": [], "y_m": []}, "empty"),
        ({"kind": "coordinates", "x_m": [0.0, 100.0, 1000.0], "y_m": [0.0, 0.0, 0.0]}, "turbines 1 and 2 overlap"),
        ({"kind": "coordinates", "x_m": [0.0, 500.0, 570.0], "y_m": [0.0, 0.0, 0.0]}, "turbines 2 and 3 overlap"),
        ({"kind": "coordinates", "x_m": [0.0, 1.0], "y_m": [0.0]}, "one (x, y) per turbine"),
        ({"kind": "coordinates", "x_m": [0.0, float("nan")], "y_m": [0.0, 0.0]}, "non-finite"),
        ({"kind": "coordinates", "x_m": [0.0, 2.0e5], "y_m": [0.0, 0.0]}, "wrong unit"),
        ({"kind": "grid", "rows": 20, "columns": 20}, "at most"),
        ({"kind": "grid", "rows": 0, "columns": 3}, "greater than or equal to 1"),
        ({"kind": "grid", "rows": 3, "columns": 3, "column_spacing_d": 1.0}, "greater than or equal to 1.5"),
        ({"kind": "file", "name": "no-such-farm"}, "no layout file 'no-such-farm'"),
        ({"kind": "file", "name": "../../etc/passwd"}, "no layout file"),
        ({"kind": "polar"}, "does not match any of the expected tags"),
    ],
)
def test_bad_layouts_are_refused(data, message):
    with pytest.raises(ValidationError, match=message.replace("(", r"\(").replace(")", r"\)")):
        SPEC.validate_python(data)


def test_resolved_layout_refuses_overlap_for_its_rotor():
    """Coordinates fine for the benchmark rotor overlap for a rotor twice its size, and the message says so."""
    spec = CoordinateLayout(x_m=[0.0, 200.0], y_m=[0.0, 0.0])
    with pytest.raises(ValueError, match=r"200\.0 m apart \(0\.87 D\); the minimum is 1\.5 D = 345\.0 m"):
        spec.resolve(230.0)
    with pytest.raises(ValueError, match="empty"):
        FarmLayout(np.array([]), np.array([]), D)
    with pytest.raises(ValueError, match="rotor diameter"):
        FarmLayout(np.zeros(1), np.zeros(1), -1.0)


def test_layout_arrays_are_read_only():
    layout = SEED001_LAYOUT.resolve(D)
    with pytest.raises(ValueError, match="read-only"):
        layout.x[0] = 1.0


def test_wind_frame_conventions():
    """Meteorological directions: 270° blows towards +x (east), 0° towards −y (south), 90° towards −x."""
    layout = FarmLayout(np.array([0.0, 1000.0, 0.0]), np.array([0.0, 0.0, 1000.0]), D)
    west = layout.wind_frame(270.0)
    assert west.downwind.tolist() == pytest.approx([0.0, 1000.0, 0.0])
    assert west.crosswind.tolist() == pytest.approx(np.array([0.0, 0.0, 1000.0]) - 1000.0 / 3)  # +y is to the left
    north = layout.wind_frame(0.0)
    assert north.downwind.tolist() == pytest.approx([1000.0, 1000.0, 0.0])  # the northern turbine is in front
    east = layout.wind_frame(90.0)
    assert east.downwind.tolist() == pytest.approx([1000.0, 0.0, 1000.0])
    x = layout.along_wind_matrix(315.0)
    assert np.allclose(x, -x.T)
    assert x[0, 1] == pytest.approx(1000.0 / math.sqrt(2.0))  # a north-westerly: turbine 2 is downwind of 1


@settings(max_examples=40, deadline=None)
@given(
    st.floats(0.0, 360.0),
    st.floats(-180.0, 180.0),
    st.lists(st.tuples(st.integers(0, 30), st.integers(0, 30)), min_size=1, max_size=12, unique=True),
)
def test_wind_frame_turns_with_the_layout(direction, turn, cells):
    """Rotating the layout by α (clockwise) and the wind by α leaves every turbine's wind-frame coordinates."""
    pts = np.array(cells, dtype=float) * 2.0 * D
    layout = FarmLayout(pts[:, 0], pts[:, 1], D)
    a = math.radians(turn)
    rotated = FarmLayout(
        pts[:, 0] * math.cos(a) + pts[:, 1] * math.sin(a), -pts[:, 0] * math.sin(a) + pts[:, 1] * math.cos(a), D
    )
    one, two = layout.wind_frame(direction), rotated.wind_frame(direction + turn)
    assert np.allclose(one.downwind, two.downwind, atol=1e-6)
    assert np.allclose(one.crosswind, two.crosswind, atol=1e-6)


def test_groups_are_anchored_not_chained():
    """A line slanting 0.4 tolerance per turbine is cut into groups no wider than the tolerance."""
    x = np.arange(8) * 0.4 * 50.0
    layout = FarmLayout(x, np.arange(8) * 300.0, D)
    groups = layout.groups_along_wind(270.0, tolerance_m=50.0)
    assert groups == [(0, 1, 2), (3, 4, 5), (6, 7)]
    s = layout.wind_frame(270.0).downwind
    assert all(s[list(g)].max() - s[list(g)].min() <= 50.0 for g in groups)
    with pytest.raises(ValueError, match="tolerance_m"):
        layout.groups_along_wind(270.0, tolerance_m=-1.0)


def test_horns_rev_columns_face_a_wind_across_them():
    """Horns Rev 1's columns run along bearing ≈ 173°: a wind from 263° faces ten columns of eight."""
    layout = HORNS_REV_1.resolve(D)
    groups = layout.groups_along_wind(263.0, tolerance_m=0.5 * D)
    assert [len(g) for g in groups] == [8] * 10
    assert numbers(groups)[0] == (1, 2, 3, 4, 5, 6, 7, 8)
