"""evo's result zip (`evo_ape/evo_rpe --save_results`, read by `evo_res`), written and read
without evo (GPL: the format is reproduced from its documented layout, no code copied).

Layout (ZIP_STORED): `info.json` (title, ref_name, est_name, label), `stats.json` (rmse, mean,
median, std, min, max, sse), one `<name>.npy` per array (`error_array`, `timestamps`,
`seconds_from_start`, `distances_from_start`, `distances`, `alignment_transformation_sim3`),
and optionally trajectories as `.tum`/`.kitti` text (read here only as names).

Reading never unpickles: arrays are loaded with allow_pickle=False, so an object array in a
zip is an error, not code execution.
"""

from __future__ import annotations

import io
import json
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from mrnc_eval.errors import InputError
from mrnc_eval.evaluation.ape import ApeResult, path_lengths
from mrnc_eval.evaluation.modes import AlignMode, DeltaUnit
from mrnc_eval.evaluation.relations import TITLES
from mrnc_eval.evaluation.rpe import RpeResult

STAT_NAMES = ("rmse", "mean", "median", "std", "min", "max", "sse")
MAX_MEMBER_BYTES = 2 << 30  # a member larger than this is refused (zip bombs)


@dataclass(frozen=True, kw_only=True)
class EvoResult:
    """One evo result: what evo_res tabulates and plots."""

    info: dict[str, str]
    stats: dict[str, float]
    arrays: dict[str, NDArray[np.float64]] = field(default_factory=dict)
    trajectory_names: tuple[str, ...] = ()

    @property
    def title(self) -> str:
        return self.info.get("title", "")

    @property
    def est_name(self) -> str:
        return self.info.get("est_name", "")


def evo_zip_bytes(result: EvoResult) -> bytes:
    """`result` as the bytes of evo's zip (ZIP_STORED); the caller writes them under the one
    overwrite rule (mrnc_eval.outputs)."""
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", compression=zipfile.ZIP_STORED) as archive:
        archive.writestr("info.json", json.dumps(result.info))
        archive.writestr("stats.json", json.dumps({k: float(v) for k, v in result.stats.items()}))
        for name, array in result.arrays.items():
            member = io.BytesIO()
            np.save(member, np.asarray(array, dtype=np.float64), allow_pickle=False)
            archive.writestr(f"{name}.npy", member.getvalue())
    return buf.getvalue()


def _json_member(archive: zipfile.ZipFile, name: str, path: Path) -> dict[str, object]:
    try:
        value = json.loads(archive.read(name).decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as err:
        raise InputError(path, f"{name} in the evo result zip is not JSON: {err}") from None
    if not isinstance(value, dict):
        raise InputError(path, f"{name} in the evo result zip is not a JSON object")
    return value


def read_evo_zip(path: str | Path) -> EvoResult:
    """An evo result zip; InputError naming the file and the problem when it is not one."""
    path = Path(path)
    try:
        with zipfile.ZipFile(path) as archive:
            members = {m.filename: m for m in archive.infolist()}
            if not {"info.json", "stats.json"} <= members.keys():
                raise InputError(path, "not an evo result zip (no info.json and stats.json)")
            if any(m.file_size > MAX_MEMBER_BYTES for m in members.values()):
                raise InputError(path, "a member of the zip is larger than 2 GiB; refused")
            info = {str(k): str(v) for k, v in _json_member(archive, "info.json", path).items()}
            raw_stats = _json_member(archive, "stats.json", path)
            stats: dict[str, float] = {}
            for k, v in raw_stats.items():
                if not isinstance(v, (int, float)):
                    raise InputError(path, f"stats.json: {k!r} is not a number")
                stats[str(k)] = float(v)
            arrays: dict[str, NDArray[np.float64]] = {}
            for name in members:
                if not name.endswith((".npy", ".npz")) or "/" in name:
                    continue
                try:
                    loaded = np.load(io.BytesIO(archive.read(name)), allow_pickle=False)
                except ValueError as err:  # object arrays need pickle: refused
                    raise InputError(path, f"{name}: not a plain numeric array ({err})") from None
                if isinstance(loaded, np.lib.npyio.NpzFile):
                    raise InputError(path, f"{name}: an .npz archive, expected one array")
                if loaded.dtype.kind not in "fiub":
                    raise InputError(path, f"{name}: dtype {loaded.dtype} is not numeric")
                arrays[name.rsplit(".", 1)[0]] = loaded.astype(np.float64)
            trajs = tuple(n.rsplit(".", 1)[0] for n in members if n.endswith((".tum", ".kitti")))
    except zipfile.BadZipFile as err:
        raise InputError(path, f"not a zip file ({err})") from None
    except FileNotFoundError:
        raise InputError(path, "no such file") from None
    return EvoResult(info=info, stats=stats, arrays=arrays, trajectory_names=trajs)


_ALIGN_NOTES = {AlignMode.se3: "(with SE(3) Umeyama alignment)", AlignMode.sim3: "(with Sim(3) Umeyama alignment)",
                AlignMode.scale: "(scale corrected)", AlignMode.none: "(not aligned)",
                AlignMode.origin: "(with origin alignment)", AlignMode.yaw: "(with 4-DoF yaw alignment)"}


def evo_title(result: ApeResult | RpeResult, *, all_pairs: bool = False, delta_text: str | None = None) -> str:
    """The title evo gives the same computation (evo_res warns when titles differ). `delta_text`:
    the RPE delta as evo prints it (its default is the integer 1, a value typed is a float: "2.0")."""
    unit = result.unit or "unit-less"
    if isinstance(result, ApeResult):
        title = f"APE w.r.t. {TITLES[result.relation]} ({unit})"
    else:
        delta_unit = "frames" if result.delta_unit is DeltaUnit.frames else "m"
        delta = delta_text if delta_text is not None else repr(float(result.delta))
        title = f"RPE w.r.t. {TITLES[result.relation]} ({unit})\nfor delta = {delta} ({delta_unit})"
        title += " using all pairs" if all_pairs else " using consecutive pairs"
    a = result.alignment
    mode = a.mode if a is not None else AlignMode.none
    title += "\n" + _ALIGN_NOTES[mode]
    if a is not None and mode in (AlignMode.se3, AlignMode.sim3, AlignMode.scale) and a.n_to_align is not None:
        title += f" (aligned poses: {a.n_to_align})"
    plane = result.pair.plane if result.pair is not None else None
    if plane:
        title += f"\n(projected to {plane} plane)"
    return title


def evo_result(result: ApeResult | RpeResult, *, ref_name: str, est_name: str, all_pairs: bool = False,
               delta_text: str | None = None, with_stamps: bool = True) -> EvoResult:
    """What evo_ape/evo_rpe --save_results store for the same computation. APE: the arrays per
    matched pose (distances_from_start along the reference, distances along the aligned
    estimate). RPE: per pair end j, the paths reduced to the first pose and the pair ends (so the
    distances are chord sums, as evo's)."""
    kind = "APE" if isinstance(result, ApeResult) else "RPE"
    info = {"title": evo_title(result, all_pairs=all_pairs, delta_text=delta_text), "ref_name": ref_name,
            "est_name": est_name, "label": f"{kind} ({result.unit or 'unit-less'})"}
    arrays: dict[str, NDArray[np.float64]] = {"error_array": result.errors}
    pair = result.pair
    if with_stamps and pair is not None:
        stamps = pair.est.stamps
        if isinstance(result, ApeResult):
            keep = np.arange(stamps.size)
            arrays.update(seconds_from_start=stamps - stamps[0], timestamps=stamps)
        else:
            assert result.pair_ends is not None
            keep = np.concatenate([[0], result.pair_ends])
            arrays.update(seconds_from_start=(stamps[keep] - stamps[0])[1:], timestamps=stamps[keep][1:])
        ref_d, est_d = path_lengths(pair.ref_xyz[keep]), path_lengths(pair.est_xyz[keep])
        if kind == "RPE":
            ref_d, est_d = ref_d[1:], est_d[1:]
        arrays.update(distances_from_start=ref_d, distances=est_d)
    a = result.alignment
    if a is not None and a.mode is not AlignMode.none:
        arrays["alignment_transformation_sim3"] = a.sim3()
    return EvoResult(info=info, stats=dict(result.stats), arrays=arrays)
