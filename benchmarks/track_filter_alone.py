"""The GNSS track's filter alone on the open line's fixes (docs/simulation.md, "Eighth session"): for each
log, `gnss_track.track_filter` (slam.gps as configured, plus --set) on every usable fix, its position at
the fix against the truth antenna after 8.5 s, RMS after its own yaw + translation fit (m): the online
APE's counterpart where the track carries x and y, without the SLAM's discrete decisions (seconds, not
a SLAM run per log).

Usage (from /tmp, logs made by wheel_gnss_matrix.py):

    python benchmarks/track_filter_alone.py --gnss float rtk --seeds 0 1 2 3 4 5 \
        [--set track_model=steps --set track_jump_sigma_m=2.5]
"""

from __future__ import annotations

import argparse
import json
import statistics
from dataclasses import fields, replace
from pathlib import Path

import numpy as np

from benchmarks.no_wheel_trace import own_fit_rms, truth_antenna
from mrnc_eval.geodesy import lla_to_enu
from mrnc_eval.io import open_log
from mrnc_eval.io.trajectory_files import read_tum
from mrnc_eval.sim.config import GnssSimConfig
from mrnc_eval.slam.config import GpsConfig
from mrnc_eval.slam.gnss_track import track_filter

SETTLED_S = 8.5  # s after the first fix: the final alignment is fixed by then on every seed


def fixes_and_truth(log: Path) -> dict[str, np.ndarray]:
    """The log's usable fixes (stamps s, ENU xy m about the sim's origin, sigma m) and the truth antenna there."""
    with open_log(log) as lg:
        gnss, lever = lg.gnss(), lg.transform("base_link", "gnss")[:3, 3]
    assert gnss is not None
    var = np.diagonal(gnss.covariance, axis1=1, axis2=2)[:, :2]
    usable = np.all(var <= GpsConfig().gps_cov_threshold_m2, axis=1) & np.all(np.isfinite(gnss.enu), axis=1)
    origin = lla_to_enu(np.array([GnssSimConfig().origin_lla]), gnss.origin_lla)[0, :2]
    stamps = gnss.stamps[usable]
    return {"t": stamps, "z": gnss.enu[usable, :2] - origin, "sigma": np.sqrt(np.max(var[usable], axis=1)),
            "truth": truth_antenna(read_tum(log.with_suffix(".gt.tum")), stamps, lever)}


def filter_rms(d: dict[str, np.ndarray], cfg: GpsConfig) -> float:
    """The filter's own-fit RMS (m) against the truth after SETTLED_S."""
    f = track_filter(cfg)
    pos = []
    for t, z, s in zip(d["t"], d["z"], d["sigma"], strict=True):
        f.update(float(t), z, float(s))
        pos.append(f.predict(float(t))[0][:2])
    keep = d["t"] - d["t"][0] > SETTLED_S
    return own_fit_rms(np.array(pos)[keep], d["truth"][keep])


def parse_sets(sets: list[str]) -> GpsConfig:
    """GpsConfig with KEY=VALUE overrides (slam.gps field names; JSON values, else strings)."""
    types = {f.name for f in fields(GpsConfig)}
    over: dict[str, object] = {}
    for s in sets:
        key, value = s.split("=", 1)
        if key not in types:
            raise SystemExit(f"unknown slam.gps key {key}")
        try:
            over[key] = json.loads(value)
        except json.JSONDecodeError:
            over[key] = value
    return replace(GpsConfig(), **over)  # type: ignore[arg-type]


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--logs", type=Path, default=Path("/tmp/wheels_logs"))
    p.add_argument("--gnss", nargs="+", choices=["float", "rtk"], default=["float"])
    p.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2, 3, 4, 5])
    p.add_argument("--set", dest="sets", action="append", default=[], help="slam.gps KEY=VALUE (repeatable)")
    a = p.parse_args()
    cfg = parse_sets(a.sets)
    for gnss in a.gnss:
        rms = {s: filter_rms(fixes_and_truth(a.logs / f"line_calibrated_{gnss}_s{s}.mcap"), cfg) for s in a.seeds}
        print(f"{gnss}: median / worst {statistics.median(rms.values()):.3f} / {max(rms.values()):.3f} m | "
              + " ".join(f"{s}: {v:.3f}" for s, v in rms.items()), flush=True)


if __name__ == "__main__":
    main()
