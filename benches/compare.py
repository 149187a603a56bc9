"""slam2world side by side with its peers, in one process: one table of medians and ratios.

Usage::

    python benches/compare.py [--quick | --smoke] [--only AREA[,AREA]] [--json PATH]
                              [--curves DIR] [--threads 1,2] [--check]

Areas (rows in ``benches/peers/``): align (numpy vectorised Umeyama, evo),
transform (numpy float32/float64, Open3D when installed, a copy of the same
bytes), backproject (numpy viewer rules), octree (OctoMap ``insertPointCloud``,
memory per leaf), mcap (Python ``mcap`` + ros1 decoding; plain zstd), rosbag
(``rosbags`` reader + deserialisation; plain lz4 / bz2 decompression).

Each row runs our function and a peer's on the same input and reports the
median wall time of each, ``ratio = peer / ours`` per element (above 1: we are
faster), the same ratio of process CPU time (all threads: steadier on a loaded
machine, and a penalty for our parallelism), the issue's target and whether it
is met (checked at full size only), and our throughput (today's figure).

- ``--quick``: smaller sizes (a few minutes at most); ``--smoke``: tiny sizes,
  one repeat (for the test suite; no figure means anything).
- ``--json PATH``: every number and the machine, for tracking.
- ``--curves DIR``: time against size for each operation (1e3 … 1e7 elements),
  one log-log PNG per area (``curves_<area>.png``) and ``curves.json``.
- ``--threads 1,2``: our side of the parallel rows again in subprocesses with
  ``RAYON_NUM_THREADS`` set (rayon's pool is fixed at start), as speed-up over
  the first count.

BLAS and OpenMP run one thread unless ``OPENBLAS_NUM_THREADS`` /
``OMP_NUM_THREADS`` / ``MKL_NUM_THREADS`` are set: numpy's small ``(N, 3) @ (3, 3)``
products gain nothing from BLAS threads (on a loaded machine they make them
10-20x slower, which would flatter our ratios) and OctoMap is measured on one
thread as its figures are quoted.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numpy as np  # noqa: E402  (after the thread settings)

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from peers import AREAS  # noqa: E402
from peers.registry import REGISTRY, Case, Row, Skip, Thunk  # noqa: E402


def load_rows() -> None:
    """Imports every area's module so that its rows register (once)."""
    if REGISTRY:
        return
    import peers.cloud  # noqa: F401
    import peers.core  # noqa: F401
    import peers.mcap  # noqa: F401
    import peers.octree  # noqa: F401
    import peers.rosbag  # noqa: F401


@dataclass
class Timing:
    """Median wall time and median process CPU time (all threads) per call."""

    median_s: float
    cpu_s: float
    repeats: int


def _once(fn: Thunk) -> tuple[float, float]:
    c0, t0 = time.process_time(), time.perf_counter()
    fn()
    return time.perf_counter() - t0, time.process_time() - c0


def measure(fn: Thunk, budget_s: float, max_repeats: int) -> Timing:
    """Median wall time of ``fn``: one warm-up call, then repeats within the
    budget (at least 3 unless ``max_repeats`` is smaller; a call longer than the
    budget is measured once, its warm-up being the measurement)."""
    return measure_pair(fn, None, budget_s, max_repeats)[0]


def measure_pair(
    ours: Thunk, peer: Thunk | None, budget_s: float, max_repeats: int
) -> tuple[Timing, Timing | None]:
    """Median wall and CPU times of ``ours`` and ``peer``, their calls
    interleaved (ours, peer, ours, …) so that a change of the machine's load
    during the row weighs on both sides alike. One warm-up call each; then as
    many rounds as fit the budget (at least 3, at most ``max_repeats``; none
    when a warm-up alone exceeds the budget: the warm-ups are the measurement)."""
    thunks = [ours] if peer is None else [ours, peer]
    first = [_once(f) for f in thunks]
    if sum(w for w, _ in first) >= budget_s or max_repeats <= 1:
        out = [Timing(w, c, 1) for w, c in first]
    else:
        n = int(min(max_repeats, max(3, budget_s / max(sum(w for w, _ in first), 1e-9))))
        samples: list[list[tuple[float, float]]] = [[] for _ in thunks]
        for _ in range(n):
            for f, acc in zip(thunks, samples):
                acc.append(_once(f))
        out = [
            Timing(statistics.median(w for w, _ in acc), statistics.median(c for _, c in acc), n)
            for acc in samples
        ]
    return out[0], (out[1] if peer is not None else None)


@dataclass
class Mode:
    name: str  # "full", "quick" or "smoke"
    budget_s: float
    max_repeats: int

    def size(self, row: Row) -> int:
        return {"full": row.size, "quick": row.quick_size, "smoke": row.smoke_size}[self.name]


def selected(only: str | None) -> list[Row]:
    load_rows()
    if not only:
        return list(REGISTRY)
    areas = {a.strip() for a in only.split(",") if a.strip()}
    unknown = areas - set(AREAS)
    if unknown:
        raise SystemExit(f"compare.py: unknown area(s) {sorted(unknown)}; areas: {AREAS}")
    return [r for r in REGISTRY if r.area in areas]


def run_row(row: Row, size: int, mode: Mode, ours_only: bool = False) -> dict[str, Any]:
    """Measures one row at one size; returns its record."""
    rec: dict[str, Any] = {
        "area": row.area,
        "row": row.name,
        "peer": row.peer,
        "size": size,
        "unit": row.unit,
        "work_unit": row.work_unit,
        "target": row.target,
        "target_text": row.target_text,
        "issue": row.issue,
    }
    try:
        case: Case = row.setup(size)
    except Skip as e:
        return {**rec, "skipped": str(e)}
    paired = case.peer if (case.values is None and not ours_only) else None
    ours, peer = measure_pair(case.ours, paired, mode.budget_s, mode.max_repeats)
    rec.update(
        ours_s=ours.median_s,
        ours_cpu_s=ours.cpu_s,
        ours_repeats=ours.repeats,
        work=case.ours_work,
        throughput_ours_per_s=case.ours_work / ours.median_s,
        extras=case.extras,
    )
    if ours_only:
        return rec
    if case.values is not None:
        v_ours, v_peer = case.values
        rec.update(ours_value=v_ours, peer_value=v_peer, ratio=v_peer / v_ours, cpu_ratio=None)
    elif peer is not None:
        peer_work = case.peer_work or case.ours_work
        per_ours, per_peer = ours.median_s / case.ours_work, peer.median_s / peer_work
        cpu_ours, cpu_peer = ours.cpu_s / case.ours_work, peer.cpu_s / peer_work
        rec.update(
            peer_s=peer.median_s,
            peer_cpu_s=peer.cpu_s,
            peer_repeats=peer.repeats,
            peer_work=peer_work,
            ratio=per_peer / per_ours,
            cpu_ratio=cpu_peer / cpu_ours if cpu_ours > 0 else None,
        )
    if row.target is not None and "ratio" in rec:
        rec["met"] = bool(rec["ratio"] >= row.target) if mode.name == "full" else None
    return rec


def fmt_rate(v: float, unit: str) -> str:
    for scale, prefix in ((1e9, "G"), (1e6, "M"), (1e3, "k")):
        if v >= scale:
            return f"{v / scale:.1f} {prefix}{unit}/s"
    return f"{v:.0f} {unit}/s"


HEADER = (
    f"{'area':11} {'row':46} {'peer':46} {'size':>9} {'ours ms':>10} {'peer ms':>10} "
    f"{'ratio':>8} {'cpu ratio':>9} {'target':>12} {'met':>5}  today"
)


def format_row(rec: dict[str, Any]) -> str:
    head = f"{rec['area']:11} {rec['row'][:46]:46} {rec['peer'][:46]:46} {rec['size']:>9}"
    if "skipped" in rec:
        return f"{head} skipped: {rec['skipped']}"
    if "ours_value" in rec:
        ours, peer = f"{rec['ours_value']:.1f} B", f"{rec['peer_value']:.1f} B"
        today = f"{rec['ours_value']:.1f} B/leaf vs {rec['peer_value']:.1f} B/leaf"
    else:
        ours = f"{rec['ours_s'] * 1e3:.3f}"
        peer = f"{rec['peer_s'] * 1e3:.3f}" if "peer_s" in rec else ""
        today = fmt_rate(rec["throughput_ours_per_s"], rec["work_unit"])
    ratio = f"{rec['ratio']:.2f}x" if "ratio" in rec else ""
    cpu = f"{rec['cpu_ratio']:.2f}x" if rec.get("cpu_ratio") else ""
    met = {True: "met", False: "NOT", None: "-"}[rec.get("met")] if rec["target"] else ""
    return (
        f"{head} {ours:>10} {peer:>10} {ratio:>8} {cpu:>9} {rec['target_text']:>12} {met:>5}  "
        f"{today}"
    )


def machine() -> dict[str, Any]:
    import slam2world as s2w

    model = platform.processor()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                model = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return {
        "platform": platform.platform(),
        "cpu_model": model,
        "cpus": os.cpu_count(),
        "python": platform.python_version(),
        "numpy": np.__version__,
        "slam2world": s2w.__version__,
        "load_average": list(os.getloadavg()) if hasattr(os, "getloadavg") else None,
        "rayon_threads": os.environ.get("RAYON_NUM_THREADS"),
        "blas_threads": os.environ.get("OPENBLAS_NUM_THREADS"),
    }


def write_json(path: Path, doc: dict[str, Any]) -> None:
    """Writes ``doc`` to a temporary name beside ``path``, then renames it."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(path.suffix + ".tmp")
    tmp.write_text(json.dumps(doc, indent=2) + "\n")
    tmp.replace(path)


# ---------------------------------------------------------------- cost curves


def curves(rows: list[Row], mode: Mode, out_dir: Path, max_size: int | None) -> dict[str, Any]:
    """Times our side and the peer of every curve row at each curve size; one
    log-log PNG per area. Peers that take over ``peer_limit_s`` at one size are
    not run at the larger sizes."""
    out_dir.mkdir(parents=True, exist_ok=True)
    peer_limit_s = {"full": 30.0, "quick": 5.0, "smoke": 1.0}[mode.name]
    sizes_cap = max_size or {"full": 10**7, "quick": 10**6, "smoke": 10**3}[mode.name]
    doc: dict[str, Any] = {}
    for row in rows:
        if not row.curve:
            continue
        key = f"{row.area}: {row.name} | {row.peer}"
        series: dict[str, Any] = {"area": row.area, "unit": row.unit, "points": []}
        peer_too_slow = False
        for n in row.curve:
            if n > sizes_cap:
                break
            try:
                case = row.setup(n)
            except Skip as e:
                series["skipped"] = str(e)
                break
            paired = None if peer_too_slow else case.peer
            ours, peer = measure_pair(case.ours, paired, mode.budget_s / 2, mode.max_repeats)
            point: dict[str, Any] = {"size": n, "ours_s": ours.median_s / case.ours_work * n}
            if peer is not None:
                per = peer.median_s / (case.peer_work or case.ours_work)
                point["peer_s"] = per * n
                peer_too_slow = peer.median_s > peer_limit_s
            series["points"].append(point)
            print(f"  curve {key} n={n:.0e}: {point}", flush=True)
        doc[key] = series
    write_json(out_dir / "curves.json", doc)
    plot_curves(doc, out_dir)
    return doc


def plot_curves(doc: dict[str, Any], out_dir: Path) -> list[Path]:
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("  matplotlib not installed: curves written as JSON only")
        return []
    written = []
    for area in AREAS:
        items = [(k, v) for k, v in doc.items() if v["area"] == area and v["points"]]
        if not items:
            continue
        fig, ax = plt.subplots(figsize=(7, 5))
        drawn_ours: set[str] = set()
        for key, s in items:
            name, peer = key.split(": ", 1)[1].split(" | ")
            pts = s["points"]
            if name not in drawn_ours:
                ax.loglog([p["size"] for p in pts], [p["ours_s"] for p in pts], "o-", label=name)
                drawn_ours.add(name)
            pp = [p for p in pts if "peer_s" in p]
            if pp:
                style = "k--" if "copy" in peer else "s:"
                ax.loglog([p["size"] for p in pp], [p["peer_s"] for p in pp], style, label=peer)
        ax.set_xlabel(f"size ({items[0][1]['unit']})")
        ax.set_ylabel("median time (s)")
        ax.set_title(f"slam2world {area}: time against size")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
        path = out_dir / f"curves_{area}.png"
        fig.savefig(path, dpi=110, bbox_inches="tight")
        plt.close(fig)
        written.append(path)
    return written


# ------------------------------------------------------------- thread scaling


def thread_scaling(args: argparse.Namespace, counts: list[int]) -> list[dict[str, Any]]:
    """Our side of the parallel rows, in one subprocess per thread count."""
    by_count: dict[int, list[dict[str, Any]]] = {}
    for c in counts:
        out = Path(args.tmp_dir) / f"threads_{c}.json"
        cmd = [sys.executable, str(Path(__file__)), "--ours-only", "--json", str(out)]
        cmd += [f"--{args.mode}"] if args.mode != "full" else []
        cmd += ["--only", args.only] if args.only else []
        env = {**os.environ, "RAYON_NUM_THREADS": str(c)}
        subprocess.run(cmd, env=env, check=True, stdout=subprocess.DEVNULL)
        by_count[c] = json.loads(out.read_text())["rows"]
    base = counts[0]
    table = []
    seen: set[tuple[str, str, int]] = set()
    for i, rec in enumerate(by_count[base]):
        key = (rec["area"], rec["row"], rec["size"])
        if "skipped" in rec or not rec.get("parallel") or key in seen:
            continue
        seen.add(key)
        entry = {"area": rec["area"], "row": rec["row"], "size": rec["size"], "times_s": {}}
        for c in counts:
            entry["times_s"][str(c)] = by_count[c][i].get("ours_s")
        t0 = entry["times_s"][str(base)]
        entry["speedup"] = {str(c): t0 / t for c, t in entry["times_s"].items() if t}
        table.append(entry)
    return table


# ---------------------------------------------------------------------- main


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    g = ap.add_mutually_exclusive_group()
    g.add_argument("--quick", action="store_true", help="smaller sizes, shorter budgets")
    g.add_argument("--smoke", action="store_true", help="tiny sizes, one repeat (tests)")
    ap.add_argument("--only", metavar="AREA", help=f"comma-separated areas of {AREAS}")
    ap.add_argument("--json", type=Path, metavar="PATH", help="write the results as JSON")
    ap.add_argument("--curves", type=Path, metavar="DIR", help="cost curves (PNG + JSON) here")
    ap.add_argument("--curve-max", type=float, help="largest curve size (default by mode)")
    ap.add_argument("--threads", metavar="N,M", help="thread counts for the scaling table")
    ap.add_argument("--check", action="store_true", help="exit 1 when a row misses its target")
    ap.add_argument("--ours-only", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    args.mode = "smoke" if args.smoke else "quick" if args.quick else "full"
    mode = {
        "full": Mode("full", 2.0, 200),
        "quick": Mode("quick", 0.5, 50),
        "smoke": Mode("smoke", 0.0, 1),
    }[args.mode]
    rows = selected(args.only)

    started = time.perf_counter()
    results: list[dict[str, Any]] = []
    if not args.ours_only:
        print(HEADER)
        print("-" * len(HEADER))
    for row in rows:
        rec = run_row(row, mode.size(row), mode, args.ours_only)
        rec["parallel"] = row.parallel
        results.append(rec)
        if not args.ours_only:
            print(format_row(rec), flush=True)
    missed = [r for r in results if r.get("met") is False]

    doc: dict[str, Any] = {"machine": machine(), "mode": args.mode, "rows": results}
    if args.threads and not args.ours_only:
        import tempfile

        counts = [int(c) for c in args.threads.split(",") if c.strip()]
        with tempfile.TemporaryDirectory() as d:
            args.tmp_dir = d
            scaling = thread_scaling(args, counts)
        print(f"\nthread scaling (RAYON_NUM_THREADS = {counts}; speed-up over {counts[0]}):")
        for e in scaling:
            ups = "  ".join(f"{c}: {u:.2f}x" for c, u in e["speedup"].items())
            print(f"  {e['area']:11} {e['row'][:46]:46} {e['size']:>9}  {ups}")
        doc["thread_scaling"] = scaling
    if args.curves and not args.ours_only:
        print("\ncost curves:")
        cap = int(args.curve_max) if args.curve_max else None
        doc["curves"] = curves(rows, mode, args.curves, cap)
    doc["elapsed_s"] = time.perf_counter() - started
    if args.json:
        write_json(args.json, doc)
    if not args.ours_only:
        load = doc["machine"]["load_average"]
        print(
            f"\n{doc['machine']['cpus']} CPUs ({doc['machine']['cpu_model']}), load {load}, "
            f"{doc['elapsed_s']:.0f} s; ratio = peer time / our time per element"
        )
    return 1 if (args.check and missed) else 0


if __name__ == "__main__":
    sys.exit(main())
