"""Shared helpers of the live tests: an embedded router on a free loopback port and nodes run in threads.

Every node gets its own Zenoh session, connected to the router over TCP on 127.0.0.1 with multicast scouting off,
so messages really cross the transport (a router on loopback), as between processes.
"""

from __future__ import annotations

import contextlib
import threading
import time
import tomllib
from collections.abc import Callable, Iterator
from pathlib import Path

from windwarden.live.config import PlantSettings, SupervisorSettings
from windwarden.live.plant_node import PlantNode
from windwarden.live.router import free_port, open_router
from windwarden.live.supervisor_node import SupervisorNode
from windwarden.live.transport import open_session
from wwcore.scenario import Scenario, parse_scenario

HYDRO_SHORT = """
name = "hydro-short"
duration_s = 12.0
[plant]
kind = "hydro"
[wind]
mean = [[0.0, 7.5]]
turbulence_intensity = 0.15
length_scale_m = 340.0
[supervisor]
params = { tau_filter = [0.03, 0.03] }
[[faults]]
name = "pump"
target = "u_p"
kind = "offset"
value = -0.3
start_s = 3.0
end_s = 8.0
"""

TURBINE_SHORT = """
name = "turbine-short"
duration_s = 30.0
[plant]
kind = "turbine"
[wind]
mean = [[0.0, 12.0], [30.0, 14.0]]
[[faults]]
name = "generator sensor 2 stuck"
target = "omega_g_m2"
kind = "fixed"
value = 100.0
start_s = 12.0
end_s = 17.0
[[faults]]
name = "double: rotor sensor 2"
target = "omega_r_m2"
kind = "gain"
value = 1.1
start_s = 20.0
end_s = 26.0
[[faults]]
name = "double: generator sensor 1"
target = "omega_g_m1"
kind = "gain"
value = 0.9
start_s = 20.0
end_s = 26.0
"""

FARM_SHORT = """
name = "farm-short"
duration_s = 70.0
[plant]
kind = "farm"
wind_case = 2
[plant.demand]
mode = "available_fraction"
fraction = 0.8
update_s = 10.0
[wind]
mean = [[0.0, 10.0], [70.0, 10.875]]
# the debris window after the scorecard's 60-s warm-up, so that the scorecards compared hold a scored window
[[faults]]
name = "F1 debris wt5"
target = "rotor"
kind = "debris"
value = 0.97
turbine = 5
start_s = 62.0
end_s = 68.0
# the drive-train hold with its 3P cancellation and the farm's ripple compensation, and the pitch trim: every
# field farm.refs carries crosses the wire
[[faults]]
name = "F3 drive train wt4"
target = "drivetrain"
kind = "drivetrain_wear"
value = 5.0
turbine = 4
start_s = 30.0
end_s = 60.0
[[faults]]
name = "F2 pitch misalignment wt7"
target = "pitch_actuator_3"
kind = "offset"
value = 0.3
turbine = 7
start_s = 40.0
end_s = 55.0
"""


def scenario(text: str, **update: object) -> Scenario:
    s = parse_scenario(tomllib.loads(text))
    return s.model_copy(update=update) if update else s


@contextlib.contextmanager
def router() -> Iterator[str]:
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    with open_router([endpoint]):
        yield endpoint


def wait_for(predicate: Callable[[], bool], timeout: float, interval: float = 0.02) -> bool:
    """Poll a condition that can only be observed by polling (files, HTTP) until true or ``timeout``."""
    deadline = time.monotonic() + timeout
    while not predicate():
        if time.monotonic() > deadline:
            return False
        time.sleep(interval)
    return True


class LiveNodes:
    """A supervisor and a plant, each in a thread with its own session; ``plant.run()`` result in ``code``."""

    def __init__(
        self,
        endpoint: str,
        scn: Scenario,
        run_dir: Path,
        *,
        mode: str = "lockstep",
        speed: float = 1.0,
        seed: int = 0,
        supervisor: bool = True,
        rerun_url: str | None = None,
        **plant_options: object,
    ):
        self.run_dir = run_dir
        self.sup_settings = SupervisorSettings(connect=endpoint, run_dir=run_dir)
        self.plant_settings = PlantSettings(
            connect=endpoint, mode=mode, speed=speed, seed=seed, run_dir=run_dir, **plant_options
        )
        self.scenario = scn
        self.with_supervisor = supervisor
        self.rerun_url = rerun_url
        self.code: int | None = None
        self.error: BaseException | None = None
        self.done = threading.Event()

    def __enter__(self) -> LiveNodes:
        self._sessions = []
        if self.with_supervisor:
            s = open_session(self.sup_settings)
            self._sessions.append(s)
            factory = None
            if self.rerun_url:
                from dashboards.live import LiveRecording

                def factory(info):
                    return LiveRecording(
                        info.kind,
                        "supervisor",
                        info.run_id,
                        self.rerun_url,
                        turbines=list(dict.fromkeys(info.turbines)),
                    )

            self.supervisor = SupervisorNode(s, self.sup_settings, factory)
            self._sup_thread = threading.Thread(target=self.supervisor.run, daemon=True)
            self._sup_thread.start()
        p = open_session(self.plant_settings)
        self._sessions.append(p)
        display = None
        if self.rerun_url:
            from dashboards.live import LiveRecording

            display = LiveRecording(
                self.scenario.plant.kind,
                "plant",
                self.run_dir.name,
                self.rerun_url,
                n_turbines=self.scenario.plant.n_turbines,
                plant_section=self.scenario.plant,
            )
        self.plant = PlantNode(p, self.plant_settings, self.scenario, self.run_dir.name, self.run_dir, display)
        self._plant_thread = threading.Thread(target=self._run_plant, daemon=True)
        self._plant_thread.start()
        return self

    def _run_plant(self) -> None:
        try:
            self.code = self.plant.run()
        except BaseException as error:  # surfaced by wait()
            self.error = error
        finally:
            self.done.set()

    def wait(self, timeout: float) -> int:
        assert self.done.wait(timeout), f"the plant did not finish within {timeout} s"
        if self.error is not None:
            raise self.error
        return self.code

    def __exit__(self, *exc: object) -> None:
        self.plant.stop()
        self._plant_thread.join(10)
        if self.with_supervisor:
            self.supervisor.stop()
            self._sup_thread.join(10)
            self.supervisor.close()
        self.plant.close()
        for s in self._sessions:
            s.close()
