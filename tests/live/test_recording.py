"""The Rerun recording of a live run: plant and supervisor (two sessions, two recording streams with the run's
recording id) land in one ``recording.rrd`` through the recorder, which ``rerun rrd verify`` accepts, with the
hydrostatic dashboard's entities: reconstruction vs truth, commands nominal vs corrected vs applied, states."""

from __future__ import annotations

import re
import subprocess

from tests.live.helpers import HYDRO_SHORT, LiveNodes, router, scenario, wait_for
from windwarden.live.finalize import finalize_recording, recording_entities, verify_recording
from windwarden.live.recorder import recorder_command, start, stop
from windwarden.live.runfolder import RECORDING


def test_hydro_run_records_one_recording_with_the_dashboard_entities(tmp_path):
    run_dir = tmp_path / "run"
    run_dir.mkdir()
    rec = recorder_command(run_dir / RECORDING)
    recorder = start(rec.recorder, tmp_path / "recorder.log")
    try:
        assert wait_for(lambda: (run_dir / RECORDING).exists(), 20)
        with (
            router() as endpoint,
            LiveNodes(endpoint, scenario(HYDRO_SHORT), run_dir, mode="lockstep", rerun_url=rec.url) as nodes,
        ):
            assert nodes.wait(120) == 0
    finally:
        stop(recorder)
    assert verify_recording(run_dir / RECORDING, footers=False)  # the streamed file, before it is closed
    assert finalize_recording(run_dir) and verify_recording(run_dir / RECORDING)
    entities = recording_entities(run_dir / RECORDING)
    base = "/turbine/1"
    plant_side = {
        f"{base}/hydro/f/u_p/plant",  # the true offset
        f"{base}/hydro/f/u_M/plant",
        f"{base}/hydro/commands/u_p/plant",  # nominal vs corrected vs applied
        f"{base}/speed/omega_g/plant",  # sensor and truth
        f"{base}/hydro/pressure/plant",
        f"{base}/faults/injected/u_p",
        "/run/timing",
    }
    supervisor_side = {
        f"{base}/hydro/f/u_p/supervisor",  # reconstruction (35) and filtered (37)
        f"{base}/hydro/f/u_M/supervisor",
        f"{base}/speed/omega_g/supervisor",  # observer
        f"{base}/hydro/pressure/supervisor",
        f"{base}/residuals/supervisor",
        f"{base}/faults/detected/u_p",
    }
    assert plant_side <= entities, plant_side - entities
    assert supervisor_side <= entities, supervisor_side - entities
    stores = subprocess.run(
        [rec.recorder[0], "rrd", "print", str(run_dir / RECORDING)], capture_output=True, text=True, timeout=60
    ).stdout
    recordings = set(re.findall(r'StoreId\(\s*Recording,\s*"([^"]+)",\s*"([^"]+)"', stores))
    assert recordings == {("windwarden", "run")}, "one recording: the run's id, both processes"
