"""`mrnc-eval control LOG --mode identify`: the drive (gain, dead band, time constant, transport
delay per side, with 1-sigma uncertainty) fitted to the log's pump commands and wheel speeds
(control/identify.py), written as a result and as `identified_plant.yaml`, a configuration file
that runs `control --mode simulate` and `--mode sweep` on the identified plant (--config FILE)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

from mrnc_eval.config import Config, config_hash, dump_config
from mrnc_eval.control.closed_loop import SIDES
from mrnc_eval.control.identify import DriveEstimate, IdentificationError, identify_side
from mrnc_eval.errors import InputError
from mrnc_eval.io.control_recording import read_drive_record
from mrnc_eval.results import Metric, RunResult, log_id_for, write_result
from mrnc_eval.tables import Cell, Table

PLANT_FILE = "identified_plant.yaml"
ROWS = [("Gain K ((m/s)/RPM)", "gain_mps_per_rpm", "gain_sd"), ("Dead band (RPM)", "dead_band_rpm", "dead_band_sd"),
        ("Time constant tau (s)", "tau_s", "tau_sd"), ("Transport delay (s)", "delay_s", "delay_sd")]


def identify_log(log_path: Path, cfg: Config) -> tuple[dict[str, DriveEstimate], dict[str, str]]:
    speeds, cmds, topics = read_drive_record(log_path, cfg.io, cfg.robot.wheel_radius_m)
    ic = cfg.control.identify
    out = {}
    for side in SIDES:
        try:
            out[side] = identify_side(speeds.stamps, getattr(speeds, side), cmds.stamps, getattr(cmds, side),
                                      max_delay_s=ic.max_delay_s, signal=ic.command_signal)
        except IdentificationError as err:
            raise InputError(log_path, f"{side} side: {err}", topic=topics["commands"]) from err
    return out, topics


def plant_overrides(est: dict[str, DriveEstimate], cfg: Config) -> dict[str, Any]:
    """control.plant (both sides) and control.sweep ranges (estimate +/- sweep_sigmas sd, at least 5 %;
    the sweep draws one drive for both sides, so its ranges span both sides' estimates)."""
    k = cfg.control.identify.sweep_sigmas
    ff = cfg.control.model.feedforward_rpm_per_mps

    def span(key: str, sd_key: str, floor: float, scale: float = 1.0) -> list[float]:
        lo = min(getattr(e, key) - max(k * getattr(e, sd_key), floor * abs(getattr(e, key))) for e in est.values())
        hi = max(getattr(e, key) + max(k * getattr(e, sd_key), floor * abs(getattr(e, key))) for e in est.values())
        return [max(lo, 0.0) * scale, hi * scale]

    delay = span("delay_s", "delay_sd", 0.0)
    gain = span("gain_mps_per_rpm", "gain_sd", 0.05, ff)
    return {"control": {
        "plant": {side: {"gain_mps_per_rpm": e.gain_mps_per_rpm, "tau_s": e.tau_s, "delay_s": e.delay_s,
                         "dead_band_rpm": e.dead_band_rpm} for side, e in est.items()},
        "sweep": {"gain_mismatch": [gain[0] - 1.0, gain[1] - 1.0],
                  "dead_band_rpm": span("dead_band_rpm", "dead_band_sd", 0.05),
                  "tau_s": span("tau_s", "tau_sd", 0.05),
                  "delay_s": [max(delay[0] - 0.005, 0.0), delay[1] + 0.005]},
    }}


def run_identify(log_path: Path, cfg: Config, out_dir: Path) -> RunResult:
    est, topics = identify_log(log_path, cfg)
    result = RunResult(kind="control", log_path=str(log_path), log_id=log_id_for(log_path),
                       config_hash=config_hash(cfg))
    for side, e in est.items():
        for _label, key, sd_key in ROWS:
            unit = {"gain_mps_per_rpm": "(m/s)/RPM", "dead_band_rpm": "RPM"}.get(key, "s")
            result.metrics.append(Metric(name=key, value=float(getattr(e, key)), unit=unit,
                                         group=f"control/identified/{side}"))
            result.metrics.append(Metric(name=sd_key, value=float(getattr(e, sd_key)), unit=unit,
                                         group=f"control/identified/{side}"))
        result.metrics.append(Metric(name="rms_residual_mps", value=e.rms_residual_mps, unit="m/s",
                                     group=f"control/identified/{side}"))
    notes = [f"Output-error fit of v <- a v + (1 - a) K deadband(u(t - d)) per side to {topics['wheel_speeds']} "
             f"(wheel speeds) and {topics['commands']} (pump commands, {cfg.control.identify.command_signal} between "
             "messages); +/- 1 sigma from the fit's Jacobian and the delay profile. Slip lowers the apparent gain.",
             f"Run the controllers on this plant: control --mode simulate --config RUN_DIR/{PLANT_FILE} (and "
             f"--mode sweep: ranges +/- {cfg.control.identify.sweep_sigmas:g} sigma)."]
    cells: list[list[Cell]] = [[f"{getattr(e, key):.6g} +/- {getattr(e, sd):.2g}" for e in est.values()]
                               for _l, key, sd in ROWS]
    cells.append([e.rms_residual_mps for e in est.values()])
    result.tables.append(Table(
        title="Drive identified from the log (per side, +/- 1 sigma)", row_labels=[r[0] for r in ROWS] + [
            "RMS residual (m/s)"], column_labels=list(est),
        cells=cells, best=None, precision=4, notes=notes))
    overrides = plant_overrides(est, cfg)
    result.extra = {"mode": "identify", "controllers": [], "labels": {}, "roles": topics, "definitions": notes,
                    "identified": {side: e.__dict__ for side, e in est.items()}, "plant_file": PLANT_FILE,
                    "overrides": overrides}
    tmp = out_dir.parent / f".{out_dir.name}.{PLANT_FILE}"
    tmp.write_text(yaml.safe_dump(overrides, sort_keys=False))
    write_result(result, out_dir, dump_config(cfg), files={PLANT_FILE: tmp})
    return result
