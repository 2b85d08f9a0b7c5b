"""The claims matrix's open line and loop (benchmarks/wheel_gnss_matrix.py): field profile, OS0-32 x 512,
40 s, a 40 m line at 1 m/s (the 20 m loop at 0.7 m/s: at 1 m/s RAID's safety constraint stops the
machine in the loop's first corners), low-bandwidth packets, float GNSS; the slow tests simulate them
with their own wheels and seed."""

from __future__ import annotations

from pathlib import Path

from mrnc_eval.config import Config, replace_paths

DRIVE = {"sim.path_size_m": 40.0, "control.pure_pursuit.desired_speed_mps": 1.0,
         "control.pure_pursuit.max_speed_mps": 1.0, "control.pure_pursuit.speed_cap": False,
         "control.actuator.u_max_rpm": 4000.0, "sim.lidar.packet_profile": "RNG15_RFL8_NIR8",
         "sim.gnss.mode": "float"}
LOOP_SPEED = {"control.pure_pursuit.desired_speed_mps": 0.7, "control.pure_pursuit.max_speed_mps": 0.7}
# The loop asked for at 1 m/s, as the claims matrix had it until the tenth session: RAID's safety constraint
# stops the machine in the first corners after 13 m and it stands for the rest of the log. Two slow tests keep
# it on purpose: the moving-start rule needs the gyro's standing spread from a stationary stretch in the log,
# and a 100 ms wheel lag costs APE there (on the 0.7 m/s loop, seed 1, it does not; docs/simulation.md).
STOPPING_LOOP = {"control.pure_pursuit.desired_speed_mps": 1.0, "control.pure_pursuit.max_speed_mps": 1.0}
COMBINED_WHEELS = {"sim.wheels.scale_error": 0.02, "sim.wheels.lr_mismatch": 0.02, "sim.wheels.track_factor": 1.6}


def simulate_open_line(path: Path, seed: int, wheels: dict[str, object] | None = None) -> Path:
    """The open line at `path` (its .gt.tum and .errors.json beside it); `wheels`: sim.wheels.*
    overrides (default: the field profile's calibrated wheels)."""
    from mrnc_eval.recording.recorder import SimRequest, simulate_log

    return simulate_log(path, replace_paths(Config(), {**DRIVE, **(wheels or {})}),
                        SimRequest(scene="open_field", path="line", duration_s=40.0, lidar="os0-32", columns=512,
                                   seed=seed, profile="field"))


def simulate_open_loop(path: Path, seed: int, sets: dict[str, object] | None = None) -> Path:
    """The open loop (20 m, 0.7 m/s) at `path`; `sets`: config overrides (sim.wheels.*, sim.field.clock.*)."""
    from mrnc_eval.recording.recorder import SimRequest, simulate_log

    return simulate_log(path, replace_paths(Config(), {**DRIVE, **LOOP_SPEED, "sim.path_size_m": 20.0, **(sets or {})}),
                        SimRequest(scene="open_field", path="loop", duration_s=40.0, lidar="os0-32", columns=512,
                                   seed=seed, profile="field"))


def simulate_structured(path: Path, scene: str, seed: int, sets: dict[str, object] | None = None) -> Path:
    """The claims matrix's yard (its circle) or forest (a 5 m loop among the trees) at `path`, field profile,
    OS0-32 x 512, 40 s, low-bandwidth packets, float GNSS; `sets`: config overrides (sim.wheels.*)."""
    from mrnc_eval.recording.recorder import SimRequest, simulate_log

    drive = {"yard": ("circle", {}), "forest": ("loop", {"sim.path_size_m": 5.0})}
    route, size = drive[scene]
    cfg = replace_paths(Config(), {"sim.lidar.packet_profile": "RNG15_RFL8_NIR8", "sim.gnss.mode": "float", **size,
                                   **(sets or {})})
    return simulate_log(path, cfg, SimRequest(scene=scene, path=route, duration_s=40.0, lidar="os0-32", columns=512,
                                              seed=seed, profile="field"))
