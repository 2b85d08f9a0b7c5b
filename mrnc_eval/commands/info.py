"""`mrnc-eval info`: what is in a log, and is it fit for SLAM and control replay."""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from mrnc_eval.config import Config
from mrnc_eval.data import ImuSeries
from mrnc_eval.io import open_log
from mrnc_eval.text import printable

if TYPE_CHECKING:
    from mrnc_eval.io.reader import LogReader, TopicInfo
    from mrnc_eval.slam.config import ImuConfig

log = logging.getLogger(__name__)

EXPECTED_LIDAR_FIELDS = ("x", "y", "z", "t", "ring", "range", "reflectivity")


@dataclass(kw_only=True)
class Finding:
    level: str  # "ok" | "warning" | "error"
    topic: str
    message: str


@dataclass(kw_only=True)
class InfoSummary:
    path: str
    container: str
    start_s: float
    end_s: float
    duration_s: float
    topics: list[dict[str, Any]]
    roles: dict[str, str]
    findings: list[Finding] = field(default_factory=list)
    lidar: dict[str, Any] = field(default_factory=dict)
    imu_noise: dict[str, Any] | None = None  # the IMU's noise and biases from stationary stretches

    def to_json(self) -> dict[str, Any]:
        return asdict(self)

    def json_item(self) -> dict[str, Any]:
        """This summary as one `results` item of the --json document (commands/output.py)."""
        from mrnc_eval.commands.output import item

        rest = self.to_json()
        stats = {k: rest.pop(k) for k in ("duration_s", "start_s", "end_s")}
        return item(self.path, {**stats, "n_topics": len(self.topics)}, **rest)


def type_name(msgtype: str, container: str) -> str:
    """A message type as the log's ROS version writes it: sensor_msgs/Imu in a ROS 1 bag (the
    reader's type store names every type the ROS 2 way, sensor_msgs/msg/Imu)."""
    return msgtype.replace("/msg/", "/", 1) if container == "ros1" else msgtype


def run(path: Path, cfg: Config) -> InfoSummary:
    from mrnc_eval.errors import InputError
    from mrnc_eval.io.integrity import container_notes, mcap_files, verify_chunks

    damaged = [d for f in mcap_files(Path(path)) for d in verify_chunks(f).damaged]  # every chunk, decompressed
    try:
        summary = _summary(path, cfg)
    except InputError as err:
        if damaged:  # say which chunks, not only that the read failed
            raise InputError(path, f"{len(damaged)} damaged chunk(s): {damaged[0].message()}; {err.problem}") from err
        raise
    summary.findings[:0] = [Finding(level="error", topic=", ".join(d.topics), message=d.message()) for d in damaged]
    for note in container_notes(Path(path), summary.container):
        summary.findings.append(Finding(level="warning" if "MCAP" in note or "dropped" in note else "ok", topic="",
                                        message=note))
    return summary


def _summary(path: Path, cfg: Config) -> InfoSummary:
    log.info("%s: reading the overview (topics, stamps, roles)", path)
    with open_log(path, cfg.io) as lg:
        log.info("%s: %s, %d topics, %.1f s", path, lg.container, len(lg.topics), lg.duration_s)
        topics = lg.topics
        summary = InfoSummary(
            path=str(path), container=lg.container, start_s=lg.start_s, end_s=lg.end_s, duration_s=lg.duration_s,
            topics=[{"topic": t.topic, "msgtype": type_name(t.msgtype, lg.container), "count": t.count, "role": t.role,
                     "rate_hz": round(t.rate_hz, 3), "max_gap_s": round(t.max_gap_s, 6),
                     "duplicates": t.duplicates, "out_of_order": t.out_of_order, "problem": t.problem}
                    for t in topics],
            roles=lg.roles,
        )
        summary.findings.extend(Finding(level="warning", topic=d.chosen, message=d.message()) for d in lg.role_doubts)
        summary.findings.extend(_stream_findings(topics))
        _lidar_findings(lg, summary)
        _gnss_findings(lg, summary)
        imu = _validation_findings(lg, summary).get("imu")
        imu = _sensor_findings(lg, imu if isinstance(imu, ImuSeries) else None, summary, cfg)
        _imu_noise_findings(imu, summary, cfg)
    return summary


def _sensor_findings(lg: LogReader, imu: ImuSeries | None, summary: InfoSummary, cfg: Config) -> ImuSeries | None:
    """The sensors checked against each other as the SLAM checks them (commands/info_sensors.py);
    returns the IMU with its accelerometer in m/s^2 (None when it has neither unit)."""
    from mrnc_eval.commands.info_sensors import imu_and_wheel_findings, imu_in_si

    if imu is None:
        return None
    imu, found = imu_in_si(imu, summary.roles["imu"], cfg)
    usable = not any(level == "error" for level, _, _ in found)
    if usable and imu.stamps.size > 10:  # the reader screened non-finite samples out
        found += imu_and_wheel_findings(lg, imu, cfg)
    summary.findings.extend(Finding(level=lv, topic=t, message=m) for lv, t, m in found)
    return imu if usable else None


def _standing_start_text(imu: ImuSeries, icfg: ImuConfig) -> str:
    """What a standing start too short for the noise gives (slam/imu_noise.py standing_start_bias), or ''."""
    from mrnc_eval.slam.imu_noise import standing_start_bias

    if icfg.standing_start_min_s <= 0:
        return ""
    start = standing_start_bias(imu.stamps, imu.acc, imu.gyro, min_s=icfg.standing_start_min_s,
                                max_rate=icfg.standing_start_max_rate_rad_s)
    return "" if start is None else (
        f"; the {start.duration_s:.1f} s standing start gives the gyro bias "
        f"[{', '.join(f'{v:+.4f}' for v in start.gyro_bias)}] rad/s (+-{start.sigma:.1g}), graph #2's start")


def _imu_noise_findings(imu: ImuSeries | None, summary: InfoSummary, cfg: Config) -> None:
    """The IMU's noise densities and biases from the log's stationary stretches (slam/imu_noise.py),
    beside the preintegration's configured noise. `imu`: the series the validation read (None
    without an IMU role or when it was refused: already an error finding)."""
    from mrnc_eval.slam.imu_noise import estimate_imu_noise

    topic = summary.roles.get("imu")
    if topic is None or imu is None:
        return
    icfg = cfg.slam.imu
    est = estimate_imu_noise(imu.stamps, imu.acc, imu.gyro, gravity=icfg.gravity, min_s=icfg.stationary_min_s)
    if est is None:
        summary.findings.append(Finding(
            level="warning", topic=topic, message=f"no stationary stretch of {icfg.stationary_min_s:g} s or more: the "
            "IMU's noise and biases cannot be measured; the SLAM uses the configured noise (slam.imu.acc_noise, "
            f"gyro_noise){_standing_start_text(imu, icfg)}"))
        return
    summary.imu_noise = est.summary()
    b = ", ".join(f"{v:+.4f}" for v in est.gyro_bias)
    summary.findings.append(Finding(
        level="ok", topic=topic,
        message=f"IMU from {est.stationary_s:.1f} s stationary ({est.stretches} stretch(es)): noise density acc "
        f"{est.acc_noise_density:.2g} m/s^2/sqrt(Hz) (configured {icfg.acc_noise:.2g}), gyro "
        f"{est.gyro_noise_density:.2g} rad/s/sqrt(Hz) (configured {icfg.gyro_noise:.2g}); per-sample spread "
        f"{est.acc_sample_std:.2g} m/s^2, {est.gyro_sample_std:.2g} rad/s; gyro bias [{b}] rad/s "
        f"(+-{est.gyro_bias_sigma:.1g}); accelerometer bias along gravity {est.acc_bias_along_gravity:+.3f} m/s^2"))
    if est.acc_noise_density > 2 * icfg.acc_noise or est.gyro_noise_density > 2 * icfg.gyro_noise:
        summary.findings.append(Finding(level="warning", topic=topic, message="the IMU is noisier than the "
                                        "preintegration assumes (vibration?): consider slam.imu.noise_from_log=true"))


def _validation_findings(lg: LogReader, summary: InfoSummary) -> dict[str, object]:
    """Read each typed stream once through the reader's validation: a refused stream is an
    error finding, dropped samples a warning (the same policy SLAM and control replay see).
    Returns role -> the series read, for the findings that look into one."""
    from mrnc_eval.errors import InputError, NoGnssFix

    readers: dict[str, Callable[[str], object]] = {
        "imu": lg.imu, "chassis_imu": lg.imu, "gnss": lg.gnss, "wheel_speeds": lg.wheel_speeds,
        "commands": lg.commands, "ground_truth": lg.trajectory, "wheel_odom": lg.trajectory, "path": lg.waypoints}
    series: dict[str, object] = {}
    for role, read in readers.items():
        topic = summary.roles.get(role)
        if topic is None:
            continue
        try:
            series[role] = read(topic)
        except NoGnssFix as err:  # already counted by the fix-ratio finding
            summary.findings.append(Finding(level="warning", topic=topic, message=err.problem))
            continue
        except InputError as err:
            summary.findings.append(Finding(level="error", topic=topic, message=err.problem))
            continue
        for note in lg.health(topic).notes:
            summary.findings.append(Finding(level="warning", topic=topic, message=note))
    if "tf_static" in summary.roles:
        try:
            lg.static_transforms()
        except InputError as err:
            summary.findings.append(Finding(level="error", topic=summary.roles["tf_static"], message=err.problem))
    return series


def _stream_findings(topics: list[TopicInfo]) -> list[Finding]:
    out = []
    for t in topics:
        if t.problem:
            out.append(Finding(level="warning", topic=t.topic, message=f"cannot be decoded: {t.problem}"))
        if t.duplicates:
            out.append(Finding(level="warning", topic=t.topic,
                               message=f"{t.duplicates} duplicate header stamps (dropped when read)"))
        if t.out_of_order:
            out.append(Finding(level="warning", topic=t.topic,
                               message=f"{t.out_of_order} out-of-order header stamps (sorted when read)"))
        if t.role == "imu":
            level = "ok" if t.rate_hz >= 90 else "warning"
            out.append(Finding(level=level, topic=t.topic,
                               message=f"IMU rate {t.rate_hz:.1f} Hz, largest gap {t.max_gap_s * 1e3:.1f} ms"))
            if t.rate_hz > 0 and t.max_gap_s > 5.0 / t.rate_hz:
                out.append(Finding(level="warning", topic=t.topic,
                                   message=f"IMU gap of {t.max_gap_s:.3f} s (> 5 samples)"))
    return out


def _lidar_findings(lg: LogReader, summary: InfoSummary) -> None:
    topic = summary.roles.get("lidar")
    if topic is None:
        summary.findings.append(Finding(level="warning", topic="", message="no LiDAR topic (sensor_msgs/PointCloud2)"))
        return
    first = next(lg.messages(topic, ("sensor_msgs/msg/PointCloud2",)))  # one cloud is enough for the layout
    fields = [f.name for f in first.fields]
    has_time = any(f in fields for f in ("t", "time", "timestamp"))
    entry = next(t for t in summary.topics if t["topic"] == topic)
    # the sweeps a replay reads: duplicate stamps are dropped when read, so they are not counted here either
    recorded, usable = entry["count"], entry["count"] - entry["duplicates"]
    summary.lidar = {"topic": topic, "fields": fields, "height": int(first.height), "width": int(first.width),
                     "per_point_time": has_time, "sweeps": usable, "sweeps_recorded": recorded}
    missing = [f for f in ("x", "y", "z") if f not in fields]
    if missing:
        summary.findings.append(Finding(level="error", topic=topic, message=f"PointCloud2 without {'/'.join(missing)}"))
        return
    summary.findings.append(Finding(level="ok" if has_time else "warning", topic=topic,
                                    message="per-point time present" if has_time else
                                    "no per-point time field: sweeps cannot be deskewed"))
    dropped = f" ({recorded} recorded, {recorded - usable} with a duplicate stamp dropped)" if usable < recorded else ""
    summary.findings.append(Finding(level="ok", topic=topic,
                                    message=f"{usable} sweeps{dropped} of {first.height} x {first.width}"
                                    f", fields {', '.join(fields)}"))
    imu_topic = summary.roles.get("imu")
    if imu_topic is None:
        summary.findings.append(Finding(level="warning", topic=topic,
                                        message="no IMU: deskew and preintegration unavailable"))
        return
    sweep_t = np.unique(lg.sweep_stamps(topic))  # sorted, duplicates once: the sweeps a replay reads
    imu_t = np.sort(lg.stamps(imu_topic))
    from mrnc_eval.io.pointcloud import CloudFormatError, decode_cloud

    try:
        first_sweep = decode_cloud(first, 0.0)
    except CloudFormatError as err:
        summary.findings.append(Finding(level="error", topic=topic, message=f"first cloud cannot be decoded: {err}"))
        return
    if len(first_sweep) == 0:
        summary.findings.append(Finding(level="error", topic=topic,
                                        message="first cloud has no valid point (all zero or non-finite)"))
    # a sweep lasts until its last point (not until the next recorded sweep: clouds may be throttled)
    period = float(first_sweep.point_time.max()) if first_sweep.point_time is not None and len(first_sweep) else 0.1
    lo = np.searchsorted(imu_t, sweep_t, side="right") > 0  # an IMU sample at or before the sweep start
    hi = np.searchsorted(imu_t, sweep_t + period, side="left") < imu_t.size  # one at or after its end
    covered = int(np.count_nonzero(lo & hi))
    level = "ok" if covered == sweep_t.size else "warning"
    summary.findings.append(Finding(level=level, topic=topic, message=f"IMU covers {covered} of {sweep_t.size} sweeps "
                                    f"(sweep duration {period * 1e3:.0f} ms)"))


def _gnss_findings(lg: LogReader, summary: InfoSummary) -> None:
    topic = summary.roles.get("gnss")
    if topic is None:
        return
    statuses = np.asarray([m.status.status for m in lg.messages(topic, ("sensor_msgs/msg/NavSatFix",))])
    fix = int(np.count_nonzero(statuses >= 0))
    ratio = fix / statuses.size if statuses.size else 0.0
    summary.findings.append(Finding(level="ok" if ratio > 0.9 else "warning", topic=topic,
                                    message=f"GNSS fix ratio {ratio:.1%} ({statuses.size - fix} without fix)"))


def print_summary(summary: InfoSummary) -> None:
    from rich.markup import escape
    from rich.table import Table

    from mrnc_eval.text import console as terminal_console

    console = terminal_console()  # full width off a terminal
    def shown(text: str) -> str:  # log content: one line, no control characters, no rich markup
        return escape(printable(text))

    console.print(f"[bold]{shown(summary.path)}[/bold]  container {summary.container}, "
                  f"duration {summary.duration_s:.3f} s ({summary.start_s:.3f} .. {summary.end_s:.3f})")
    table = Table("topic", "type", "count", "rate Hz", "max gap s", "role")
    for t in summary.topics:
        table.add_row(shown(t["topic"]), shown(t["msgtype"]), str(t["count"]), f"{t['rate_hz']:.2f}",
                      f"{t['max_gap_s']:.3f}", t["role"] or "")
    console.print(table)
    colours = {"ok": "green", "warning": "yellow", "error": "red"}
    for f in summary.findings:
        console.print(f"[{colours[f.level]}]{f.level:7}[/] {shown(f.topic)} {shown(f.message)}")
