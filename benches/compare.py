"""slam2world side by side with its peers, in one process: medians and ratios.

Usage::

    python benches/compare.py [--quick] [--json PATH] [--only TEXT] [--check]

Each row runs our function and a peer's on the same input and reports the
median wall time of each and the ratio ``peer / ours`` (above 1: we are faster),
next to the ratio the project aims for, and the same ratio of process CPU time
(all threads; steadier on a loaded machine, and a penalty for our parallelism).
``--quick`` uses each row's smaller size; ``--json`` writes every number (and
the machine) to a file; ``--check`` exits 1 when a row misses its target.

BLAS runs one thread unless ``OPENBLAS_NUM_THREADS`` / ``OMP_NUM_THREADS`` /
``MKL_NUM_THREADS`` are set: numpy's small ``(N, 3) @ (3, 3)`` products gain
nothing from BLAS threads, and on a loaded machine those threads make them
10-20x slower, which would flatter our ratios.

Adding rows: decorate a setup function with :func:`register`. The function
takes the problem size and returns ``(ours, peer)``, two callables without
arguments that do the same work; prepare the inputs in the setup, not in the
callables. Rows of other areas may live in ``benches/compare_<area>.py``
modules: every such module is imported and registers its rows the same way
(``from compare import register``). A setup may raise :class:`Skip` (a peer or
a data file is missing); the row is then listed as skipped with the reason.
"""

from __future__ import annotations

import argparse
import importlib
import json
import os
import platform
import statistics
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numpy as np  # noqa: E402  (after the BLAS thread settings)

HERE = Path(__file__).resolve().parent
DATA = HERE.parent.parent / "shared" / "data"

Thunk = Callable[[], object]
Setup = Callable[[int], "tuple[Thunk, Thunk]"]


class Skip(Exception):
    """Raised by a setup when its row cannot run here (the reason is shown)."""


@dataclass(frozen=True)
class Row:
    """One comparison: ``name`` (what is measured), ``peer`` (against what)."""

    name: str
    peer: str
    size: int
    quick_size: int
    setup: Setup
    target: float | None = None
    unit: str = "elements"


REGISTRY: list[Row] = []


def register(
    name: str,
    *,
    peer: str,
    size: int,
    quick_size: int | None = None,
    target: float | None = None,
    unit: str = "elements",
) -> Callable[[Setup], Setup]:
    """Registers a row; ``target`` is the smallest acceptable ``peer / ours``."""

    def deco(setup: Setup) -> Setup:
        REGISTRY.append(Row(name, peer, size, quick_size or size, setup, target, unit))
        return setup

    return deco


@dataclass
class Timing:
    """Median wall time and median process CPU time (all threads) per call."""

    median_s: float
    cpu_s: float
    repeats: int
    samples: list[float] = field(default_factory=list)


def measure(fn: Thunk, budget_s: float, max_repeats: int) -> Timing:
    """Median wall time of ``fn``: one warm-up call, then repeats within the
    budget (a call longer than the budget is measured once). The CPU time is
    reported too: on a loaded machine it is the steadier of the two."""
    c0, t0 = time.process_time(), time.perf_counter()
    fn()
    first, first_cpu = time.perf_counter() - t0, time.process_time() - c0
    if first >= budget_s:
        return Timing(first, first_cpu, 1, [first])
    n = int(min(max_repeats, max(3, budget_s / max(first, 1e-9))))
    samples, cpu = [], []
    for _ in range(n):
        c0, t0 = time.process_time(), time.perf_counter()
        fn()
        samples.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    return Timing(statistics.median(samples), statistics.median(cpu), n, samples)


# ----------------------------------------------------------------- core rows


def _pairs(n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    import slam2world as s2w

    rng = np.random.default_rng(seed)
    a = rng.normal(size=(n, 3))
    t = s2w.Sim3.from_quaternion([0.1, 0.2, 0.3, 0.9], [1.0, 2.0, 3.0], 15.49)
    b = t.apply(a) + rng.normal(scale=1e-3, size=(n, 3))
    return a, b


def numpy_umeyama(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """Vectorised Umeyama on (N, 3) arrays: the numpy peer."""
    mx, my = x.mean(axis=0), y.mean(axis=0)
    xc, yc = x - mx, y - my
    var_x = np.einsum("ij,ij->", xc, xc) / len(x)
    cov = yc.T @ xc / len(x)
    u, d, vt = np.linalg.svd(cov)
    s = np.eye(3)
    if np.linalg.det(u) * np.linalg.det(vt) < 0:
        s[2, 2] = -1
    r = u @ s @ vt
    c = float(np.trace(np.diag(d) @ s) / var_x)
    return r, my - c * r @ mx, c


@register("align Sim(3)", peer="numpy vectorised Umeyama", size=10**6, quick_size=10**5, target=10)
def _align_numpy(n: int) -> tuple[Thunk, Thunk]:
    import slam2world as s2w

    a, b = _pairs(n)
    return (lambda: s2w.align(a, b)), (lambda: numpy_umeyama(a, b))


@register(
    "align Sim(3)",
    peer="evo umeyama_alignment",
    size=10**6,
    quick_size=10**5,
    target=500,
)
def _align_evo(n: int) -> tuple[Thunk, Thunk]:
    try:
        from evo.core.geometry import umeyama_alignment
    except ImportError as e:
        raise Skip(f"evo is not installed ({e})") from e
    import slam2world as s2w

    a, b = _pairs(n)
    at, bt = a.T.copy(), b.T.copy()
    return (lambda: s2w.align(a, b)), (lambda: umeyama_alignment(at, bt, True))


def _apply_rows(n: int, dtype: type) -> tuple[Any, np.ndarray, np.ndarray, np.ndarray]:
    import slam2world as s2w

    p = np.random.default_rng(1).normal(size=(n, 3)).astype(dtype)
    t = s2w.Sim3.from_quaternion([0.1, 0.2, 0.3, 0.9], [1.0, 2.0, 3.0], 15.49)
    m = (t.scale * t.rotation).T.astype(dtype)
    return t, p, m, t.translation.astype(dtype)


@register("Sim3.apply float32", peer="numpy P @ (sR).T + t", size=10**7, quick_size=10**6, target=3)
def _apply_f32(n: int) -> tuple[Thunk, Thunk]:
    t, p, m, tr = _apply_rows(n, np.float32)
    return (lambda: t.apply(p)), (lambda: p @ m + tr)


@register("Sim3.apply float64", peer="numpy P @ (sR).T + t", size=10**7, quick_size=10**6)
def _apply_f64(n: int) -> tuple[Thunk, Thunk]:
    t, p, m, tr = _apply_rows(n, np.float64)
    return (lambda: t.apply(p)), (lambda: p @ m + tr)


@register(
    "Sim3.apply float32",
    peer="numpy copy of the same bytes (the limit)",
    size=10**7,
    quick_size=10**6,
)
def _apply_copy(n: int) -> tuple[Thunk, Thunk]:
    t, p, _, _ = _apply_rows(n, np.float32)
    return (lambda: t.apply(p)), (lambda: p.copy())


@register(
    "align_trajectories fr2/desk keyframes",
    peer="evo associate + align + APE",
    size=157,
    unit="poses",
)
def _traj_evo(_: int) -> tuple[Thunk, Thunk]:
    est_path = DATA / "evo_tum_fr2_desk" / "fr2_desk_ORB_kf_mono.txt"
    ref_path = DATA / "evo_tum_fr2_desk" / "fr2_desk_groundtruth.txt"
    if not est_path.exists():
        raise Skip(f"data not present: {est_path}")
    try:
        from evo.core import metrics, sync
        from evo.tools import file_interface
    except ImportError as e:
        raise Skip(f"evo is not installed ({e})") from e
    import copy

    import slam2world as s2w

    est, ref = s2w.Trajectory.read_tum(est_path), s2w.Trajectory.read_tum(ref_path)
    e_est = file_interface.read_tum_trajectory_file(str(est_path))
    e_ref = file_interface.read_tum_trajectory_file(str(ref_path))

    def evo() -> float:
        r, e = sync.associate_trajectories(e_ref, e_est, max_diff=0.01)
        e = copy.deepcopy(e)
        e.align(r, correct_scale=True)
        ape = metrics.APE(metrics.PoseRelation.translation_part)
        ape.process_data((r, e))
        return float(ape.get_statistic(metrics.StatisticsType.rmse))

    return (lambda: s2w.align_trajectories(est, ref)), evo


# ------------------------------------------------------------------- runner


def load_plugins() -> None:
    """Imports benches/compare_*.py so that their rows register."""
    sys.path.insert(0, str(HERE))
    sys.modules.setdefault("compare", sys.modules[__name__])
    for path in sorted(HERE.glob("compare_*.py")):
        importlib.import_module(path.stem)


def fmt_time(s: float) -> str:
    return f"{s * 1e3:10.3f}"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="smaller sizes, shorter budgets")
    ap.add_argument("--json", type=Path, metavar="PATH", help="write the results as JSON")
    ap.add_argument("--only", metavar="TEXT", help="run the rows whose name or peer contains TEXT")
    ap.add_argument("--check", action="store_true", help="exit 1 when a row misses its target")
    args = ap.parse_args(argv)
    load_plugins()

    budget = 0.5 if args.quick else 2.0
    results: list[dict[str, Any]] = []
    header = (
        f"{'row':40} {'peer':42} {'size':>9} {'ours ms':>10} {'peer ms':>10} "
        f"{'ratio':>8} {'target':>7} {'cpu ratio':>10}"
    )
    print(header)
    print("-" * len(header))
    missed = 0
    for row in REGISTRY:
        if args.only and args.only not in row.name and args.only not in row.peer:
            continue
        size = row.quick_size if args.quick else row.size
        rec: dict[str, Any] = {"row": row.name, "peer": row.peer, "size": size, "unit": row.unit}
        try:
            ours, peer = row.setup(size)
        except Skip as e:
            print(f"{row.name:40} {row.peer:42} {size:>9} skipped: {e}")
            results.append({**rec, "skipped": str(e)})
            continue
        t_ours = measure(ours, budget, 200)
        t_peer = measure(peer, budget, 200)
        ratio = t_peer.median_s / t_ours.median_s
        # Targets are set for the full sizes: in quick mode they are shown, not checked.
        ok = row.target is None or ratio >= row.target or args.quick
        missed += not ok
        if row.target is None:
            target = ""
        elif args.quick:
            target = f"({row.target:g}x)"
        else:
            target = f"{row.target:g}x" + ("" if ok else " MISS")
        cpu_ratio = t_peer.cpu_s / t_ours.cpu_s if t_ours.cpu_s > 0 else float("nan")
        print(
            f"{row.name:40} {row.peer:42} {size:>9} {fmt_time(t_ours.median_s)} "
            f"{fmt_time(t_peer.median_s)} {ratio:7.1f}x {target:>7} {cpu_ratio:9.1f}x",
            flush=True,
        )
        results.append(
            {
                **rec,
                "ours_s": t_ours.median_s,
                "peer_s": t_peer.median_s,
                "ours_repeats": t_ours.repeats,
                "peer_repeats": t_peer.repeats,
                "ratio": ratio,
                "ours_cpu_s": t_ours.cpu_s,
                "peer_cpu_s": t_peer.cpu_s,
                "cpu_ratio": cpu_ratio,
                "target": row.target,
                "met": ok,
                "throughput_ours_per_s": size / t_ours.median_s,
            }
        )
    if args.json:
        import slam2world as s2w

        doc = {
            "machine": {
                "platform": platform.platform(),
                "processor": platform.processor(),
                "cpus": os.cpu_count(),
                "python": platform.python_version(),
                "numpy": np.__version__,
                "slam2world": s2w.__version__,
                "load_average": os.getloadavg() if hasattr(os, "getloadavg") else None,
                "blas_threads": os.environ.get("OPENBLAS_NUM_THREADS"),
            },
            "quick": args.quick,
            "rows": results,
        }
        tmp = args.json.with_suffix(args.json.suffix + ".tmp")
        tmp.write_text(json.dumps(doc, indent=2) + "\n")
        tmp.replace(args.json)
    return 1 if (args.check and missed) else 0


if __name__ == "__main__":
    sys.exit(main())
