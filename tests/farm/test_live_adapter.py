"""The farm's live kind: frames and references survive the wire, the supervisor answers every tick, and the
Rerun blueprint has the farm view."""

from __future__ import annotations

import numpy as np

from windwarden.kinds import RunInfo, kind_for
from wwcore.farm_frames import CANCEL_3P_MODE, DISPATCH_MODES, HOLD_TORQUE_MODE, FarmRefs
from wwcore.scenario import parse_scenario

SCENARIO = {
    "name": "farm-live",
    "duration_s": 3.0,
    "plant": {"kind": "farm", "wind_case": 2},
    "wind": {"mean": [[0.0, 10.0]]},
}


def test_frames_and_refs_round_trip_and_the_supervisor_answers_every_tick():
    kind = kind_for("farm")
    scenario = parse_scenario(SCENARIO)
    plant = kind.make_plant(scenario, seed=3)
    turbines = kind.turbines(plant)
    assert turbines == list(range(1, 10))
    sup = kind.make_supervisor(RunInfo.of(scenario, turbines, plant.dt))
    answered = []
    refs = None
    for _ in range(25):
        frame = plant.measure()
        wire_frame = kind.sensors.decode(kind.sensors.encode(kind.frame_records(frame, turbines)[0]))
        assert wire_frame["turbine"] == 1
        back = kind.frame_from_records(kind.frame_records(frame, turbines))
        assert back.sample == frame.sample and np.array_equal(back.scada, frame.scada)
        assert np.array_equal(back.mast, frame.mast) and np.array_equal(back.turbines.sensors, frame.turbines.sensors)
        plant.control(refs)
        out = sup.step(back)
        records = kind.refs_records(out, sup, turbines)
        answered.append(int(records["tick"][0]) == frame.k)
        refs = kind.refs_from_records(records)
        plant.advance()
    assert all(answered)
    assert refs is not None and refs.source_tick == 19  # computed on the farm sample closing at tick 19
    truth = kind.truth_records(plant, frame, turbines)
    assert truth["farm_power"][0] == truth["power"].sum()
    status = kind.status(sup, records, turbines)
    assert {"flagged", "dispatch_mode", "margins", "power_ref_w"} <= set(status[0])


def test_the_hold_torque_request_and_its_torque_cap_survive_the_wire():
    kind = kind_for("farm")
    scenario = parse_scenario(SCENARIO)
    plant = kind.make_plant(scenario, seed=3)
    turbines = kind.turbines(plant)
    sup = kind.make_supervisor(RunInfo.of(scenario, turbines, plant.dt))
    sup.mode = np.array([0, 3, 2, 1, 0, 0, 0, 0, 0], dtype=np.int8)  # as the dispatch leaves it
    hold = sup.mode == HOLD_TORQUE_MODE
    cap = np.where(hold, 21.5e3, np.nan)
    refs = FarmRefs(tick=9, power_ref=np.full(9, 1e6), hold_torque=hold, held_torque=cap)
    back = kind.refs_from_records(kind.refs_records(refs, sup, turbines))
    assert np.array_equal(back.hold_torque, hold) and np.array_equal(back.power_ref, refs.power_ref)
    assert np.array_equal(back.held_torque, cap, equal_nan=True)
    plain = kind.refs_from_records(kind.refs_records(FarmRefs(tick=9, power_ref=np.full(9, 1e6)), sup, turbines))
    assert np.isnan(plain.held_torque).all()  # no cap sent: NaN, which the turbine reads as its own torque


def test_the_accommodation_requests_survive_the_wire_and_every_mode_has_a_status_name():
    """Mode 5 (3P cancelled without the hold), the per-blade pitch trim and the power phasor of the ripple
    compensation come back as sent; the status names every dispatch mode (``DISPATCH_MODES``)."""
    kind = kind_for("farm")
    scenario = parse_scenario(SCENARIO)
    plant = kind.make_plant(scenario, seed=3)
    turbines = kind.turbines(plant)
    sup = kind.make_supervisor(RunInfo.of(scenario, turbines, plant.dt))
    sup.mode = np.array([0, 1, 2, 3, 4, 5, 0, 0, 0], dtype=np.int8)
    trim = np.zeros((9, 3))
    trim[4] = [0.1, -0.2, 0.1]
    phasor = np.where(np.arange(9) == 5, 0.0, -40e3 * np.exp(0.3j))
    rate = np.where(phasor != 0.0, 4.4, 0.0)
    refs = FarmRefs(
        tick=9,
        power_ref=np.full(9, 1e6),
        hold_torque=sup.mode == HOLD_TORQUE_MODE,
        cancel_3p=sup.mode == CANCEL_3P_MODE,
        pitch_trim=trim,
        ripple_power=phasor,
        ripple_rate=rate,
    )
    back = kind.refs_from_records(kind.refs_records(refs, sup, turbines))
    assert np.array_equal(back.cancel_3p, refs.cancel_3p) and np.array_equal(back.hold_torque, refs.hold_torque)
    assert np.array_equal(back.pitch_trim, trim)
    assert np.array_equal(back.ripple_power, phasor) and np.array_equal(back.ripple_rate, rate)
    status = kind.status(sup, None, turbines)
    assert [s["dispatch_mode"] for s in status[:6]] == list(DISPATCH_MODES)


def test_farm_blueprint_has_the_overview_tab():
    from dashboards.blueprints import blueprint
    from dashboards.panels import PANELS

    assert PANELS["farm"].overview is not None
    assert blueprint("farm", list(range(1, 10))) is not None


def test_the_live_plant_is_run_0_of_the_batch():
    from plant_sim.farm import FarmBatch

    kind = kind_for("farm")
    scenario = parse_scenario(SCENARIO)
    live = kind.make_plant(scenario, seed=3)
    batch = FarmBatch(scenario.plant, scenario.wind, [], seed=3, duration_s=3.0, runs=[0, 1], fault_free_twins=True)
    assert np.array_equal(live.measure().turbines.sensors, batch.measure().turbines.sensors[:9])


def test_rows_of_two_farm_samples_in_one_tick_leave_every_turbine_on_its_reference():
    """A sharded supervisor in real time: one shard answered tick k with the coordinator's new rows, the other
    (late) with the rows it held, or with no reference yet (computed_tick −1, power NaN). The plant keeps every
    turbine's reference until the rows agree: no NaN reference, no phasor referred to another sample's time."""
    kind = kind_for("farm")
    scenario = parse_scenario(SCENARIO)
    plant = kind.make_plant(scenario, seed=3)
    turbines = kind.turbines(plant)
    sup = kind.make_supervisor(RunInfo.of(scenario, turbines, plant.dt))
    records = kind.refs_records(FarmRefs(tick=21, power_ref=np.full(9, 1e6), computed_tick=19), sup, turbines)
    assert kind.refs_from_records(records).source_tick == 19
    late = records.copy()
    late["computed_tick"][4:], late["power_ref"][4:] = -1, np.nan  # shard 5-9 before its first rows
    assert kind.refs_from_records(late) is None
    late["computed_tick"][4:], late["power_ref"][4:] = 9, 2e6  # shard 5-9 on the previous sample's rows
    assert kind.refs_from_records(late) is None


def test_the_truth_frame_carries_each_turbines_true_wind_direction_and_the_dashboard_records_it():
    """``farm.truth`` v2: the direction (deg from north, 0 … <360) of the air at each turbine, as the plant carries
    the mast's across the farm (``docs/farm.md`` §1.9); a veer reaches the turbines at different times, so the rows
    differ. The farm's Rerun rows hold them in one group, beside the mast's vane."""
    from dashboards.panels import PANELS
    from wwcore.wire import FARM_TRUTH, DropReason

    kind = kind_for("farm")
    scenario = parse_scenario(
        SCENARIO
        | {
            "duration_s": 60.0,
            "plant": {"kind": "farm", "wind_direction_profile": [[0.0, 270.0], [5.0, 290.0]]},
        }
    )
    plant = kind.make_plant(scenario, seed=3)
    turbines = kind.turbines(plant)
    for _ in range(3500):  # 35 s: the turn of the profile has reached the front turbines, not the others
        frame = plant.measure()
        plant.control(None)
        plant.advance()
    truth = kind.truth_records(plant, frame, turbines)
    assert np.array_equal(truth["wind_direction"], plant.truth()["wind_direction"])
    assert ((truth["wind_direction"] >= 0.0) & (truth["wind_direction"] < 360.0)).all()
    assert np.ptp(truth["wind_direction"]) > 1.0  # the turbines see the turn at different times
    back = FARM_TRUTH.decode_frame(FARM_TRUTH.encode_frame(truth))
    assert back.tobytes() == truth.tobytes() and FARM_TRUTH.refusal(back) is None
    bad = truth.copy()
    bad["wind_direction"][3] = 400.0
    assert FARM_TRUTH.refusal(bad) == DropReason.OUT_OF_RANGE
    rows = PANELS["farm"].farm_plant(kind.frame_records(frame, turbines), truth)["direction/plant"]
    assert [rows[f"T{t}"] for t in turbines] == list(truth["wind_direction"]) and "met mast vane" in rows
