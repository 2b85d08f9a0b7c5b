"""Per-stage CPU time of `mrnc-eval ape|rpe REF EST --relation R --json`, in one fresh process, in
the order the CLI runs the stages (the files one after the other here; the CLI reads them in two
threads). Prints a Markdown table row per stage and the process's peak memory (docs/performance.md).

    PYTHONPATH=. python benchmarks/ape_stages.py ape trans REF.tum EST.tum
"""

import time

START = time.process_time()  # the interpreter's start-up, before any import of ours

import sys  # noqa: E402

ROWS: list[tuple[str, float]] = [("interpreter start (site)", START)]
_last = [START]


def mark(label: str) -> None:
    now = time.process_time()
    ROWS.append((label, now - _last[0]))
    _last[0] = now


def main(verb: str, relation: str, ref_path: str, est_path: str) -> None:
    import numpy as np
    mark("import numpy")
    from mrnc_eval import cli
    from mrnc_eval.cli_fast import fast_command
    mark("import mrnc_eval.cli (typer; no pydantic on the fast path)")
    fast_command([verb, ref_path, est_path, "--relation", relation, "--json"], {"ape": cli.ape, "rpe": cli.rpe})
    mark("parse the command line (cli_fast)")
    from mrnc_eval.commands import trajectory_eval  # noqa: F401  (imported by the CLI too)
    from mrnc_eval.evaluation import ape, rpe, stats, sync
    from mrnc_eval.evaluation.pairs import pairs_by_frames
    from mrnc_eval.io.trajectory_files import read_trajectory
    mark("import the ape/rpe command modules")
    ref = read_trajectory(ref_path)
    mark("read REF (C reader)")
    est = read_trajectory(est_path)
    mark("read EST (C reader)")
    m = sync.match(ref, est)
    mark("check + associate (nearest stamp, evo's rule)")
    pair = ape.aligned_pair(m.ref, m.est, "se3" if verb == "ape" else "none", None, None)
    mark("alignment (Umeyama SE(3); rpe: none)")
    rel = rpe.check_relation(relation)
    if verb == "rpe":
        i, j = pairs_by_frames(len(pair.est), 1, False)
        errors = rpe.pair_errors(pair, i, j, rel)
    elif relation == "trans":
        errors = ape.aligned_distances(pair)
    else:
        errors = np.degrees(ape._angles_from_quaternions(pair))
    mark(f"errors ({relation})")
    stats.error_stats(errors)
    mark("statistics (rmse, mean, median, std, min, max, sse)")
    for label, seconds in ROWS:
        print(f"| {label} | {seconds * 1000:.0f} |")
    print(f"| **total** | {_last[0] * 1000:.0f} |")
    with open("/proc/self/status") as status:
        print(next((line.strip() for line in status if line.startswith("VmHWM")), "VmHWM: n/a"))


if __name__ == "__main__":
    main(*sys.argv[1:5])
