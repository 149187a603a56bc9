"""Batch throughput of ``slam2world.batch.convert_many`` on a local Ray: logs per minute
with 1 and 2 workers over the same simulated logs (a fresh output folder per run; Ray
started once, its start-up not counted).

    .venv/bin/python benches/batch_throughput.py [--logs 8] [--reduced 8] [--workers 1 2]

Build the module with ``maturin develop --release`` first: a debug build measures the
debug build. Prints one line per worker count and the ratio to one worker.
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

import ray

from slam2world import batch
from slam2world._slam2world import run_cli


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--logs", type=int, default=8)
    p.add_argument("--reduced", type=int, default=8)
    p.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    p.add_argument("--repeat", type=int, default=1, help="runs per worker count (median)")
    a = p.parse_args()
    with tempfile.TemporaryDirectory() as d:
        root = Path(d)
        logs = []
        for seed in range(a.logs):
            log = root / f"run{seed}.mcap"
            argv = ["slam2world", "simulate", "-o", str(log), "--reduced", str(a.reduced)]
            assert run_cli([*argv, "--seed", str(seed)]) == 0
            logs.append(log)
        ray.init(num_cpus=max(a.workers), include_dashboard=False, log_to_driver=False)
        base = None
        for w in a.workers:
            rates = []
            for k in range(a.repeat):
                t = time.perf_counter()
                rows = batch.convert_many(logs, root / f"out-{w}-{k}", workers=w, progress=False)
                elapsed = time.perf_counter() - t
                assert all(r["status"] == "ok" for r in rows), rows
                rates.append(len(logs) / elapsed * 60)
            rate = statistics.median(rates)
            base = base or rate
            print(
                f"workers {w}: {rate:.1f} logs/min ({a.logs} logs, reduced {a.reduced}; "
                f"x{rate / base:.2f} of 1 worker)"
            )
        ray.shutdown()


if __name__ == "__main__":
    main()
