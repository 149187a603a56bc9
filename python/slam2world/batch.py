"""Many logs at once: one ``slam2world convert`` per log as a Ray task.

``convert_many(paths, out_dir)`` converts each log into ``out_dir/<log stem>/``
(the outputs of ``slam2world convert``, written as one set) and writes one
summary table, ``out_dir/summary.parquet`` and ``out_dir/summary.csv``, with a
row per log (:data:`COLUMNS`). A log that fails becomes a row with its error
class and message; the batch itself never fails for one log. With
``resume=True`` a log whose outputs are complete (``report.json`` and the
batch's marker naming the same input size, mtime and options) is not
converted again.

Ray is optional (``pip install 'slam2world[ray]'``) and imported only here:
without an address, ``ray.init()`` starts a local Ray on this machine (or
joins the one ``RAY_ADDRESS`` names); ``address="auto"`` or ``"ray://host:10001"``
joins an existing cluster, where every worker needs the same slam2world wheel
installed and the input and output paths on a filesystem it shares.
The per-log work is the command line's own ``convert`` (``convert_cli``):
same options, same outputs, same errors.

The console script runs it as ``slam2world batch INPUTS... -o OUT [convert
options] [--address ADDR] [--workers N] [--resume]``.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import sys
import time
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from slam2world._slam2world import convert_cli

if TYPE_CHECKING:  # pragma: no cover - typing only
    import ray.data

__all__ = ["COLUMNS", "MARKER", "convert_many", "main"]

#: The summary's columns, in order.
COLUMNS: tuple[str, ...] = (
    "path",
    "output",
    "status",
    "error_class",
    "message",
    "scale",
    "rmse",
    "pairs",
    "keyframes",
    "points",
    "octree_leaves",
    "read_s",
    "align_s",
    "backproject_s",
    "write_s",
    "total_s",
)

#: The file beside each log's outputs that says which input and options made
#: them (what ``resume`` compares).
MARKER = ".slam2world-batch.json"

_RAY_MISSING = "slam2world batch runs on Ray, which is not installed: pip install 'slam2world[ray]'"


def _import_ray() -> Any:
    try:
        import ray
    except ImportError as e:  # pragma: no cover - exercised where Ray is absent
        raise ImportError(_RAY_MISSING) from e
    return ray


def _option_args(options: Mapping[str, Any] | Sequence[str] | None) -> list[str]:
    """Convert options as command-line arguments: a list is taken as it is; a
    mapping ``{"octree": 0.2, "quiet": True}`` becomes ``--octree 0.2 --quiet``
    (``_`` → ``-``; ``True`` a flag, ``False`` / ``None`` left out; a list repeats)."""
    if options is None:
        return []
    if isinstance(options, str):
        raise TypeError("options: a mapping or a list of arguments, not one string")
    args: list[str] = []
    if not isinstance(options, Mapping):
        args = [str(a) for a in options]
    else:
        args = _mapping_args(options)
    for reserved in ("-o", "--output"):
        if reserved in args:
            raise ValueError("options: the output folder is out_dir/<log stem>, not an option")
    return args


def _mapping_args(options: Mapping[str, Any]) -> list[str]:
    args: list[str] = []
    for key, value in options.items():
        flag = "--" + key.replace("_", "-")
        if value is None or value is False:
            continue
        if value is True:
            args.append(flag)
        elif isinstance(value, (list, tuple)):
            for v in value:
                args += [flag, str(v)]
        else:
            args += [flag, str(value)]
    return args


def _stems(paths: Sequence[str]) -> list[str]:
    """The output folder name of each input: its stem, made unique by ``-2``, ``-3``…
    in input order where two inputs share one."""
    seen: dict[str, int] = {}
    out = []
    for p in paths:
        stem = Path(p.rstrip("/")).stem or "log"
        n = seen.get(stem, 0) + 1
        seen[stem] = n
        out.append(stem if n == 1 else f"{stem}-{n}")
    return out


def _identity(path: str, args: Sequence[str]) -> dict[str, Any]:
    """What makes a log's outputs: the input's size and mtime, and the options."""
    st = os.stat(path)
    return {
        "input": os.path.abspath(path),
        "size": st.st_size,
        "mtime_ns": st.st_mtime_ns,
        "options": list(args),
    }


def _complete(out: Path, identity: Mapping[str, Any]) -> bool:
    try:
        marker = json.loads((out / MARKER).read_text())
    except (OSError, ValueError):
        return False
    return marker == identity and (out / "report.json").is_file()


def _row(path: str, out: Path, status: str) -> dict[str, Any]:
    row: dict[str, Any] = dict.fromkeys(COLUMNS)
    row.update(path=path, output=str(out), status=status)
    return row


def _fill_from_report(row: dict[str, Any], out: Path) -> None:
    r = json.loads((out / "report.json").read_text())
    t = r.get("timing") or {}
    octree = r.get("octree") or {}
    row.update(
        scale=(r.get("t_world_slam") or {}).get("scale"),
        rmse=r.get("fit_rmse"),
        pairs=r.get("pairs_fitted"),
        keyframes=r.get("keyframes"),
        points=r.get("points"),
        octree_leaves=octree.get("leaves_occupied"),
        read_s=t.get("read_s"),
        align_s=t.get("align_s"),
        backproject_s=t.get("backproject_s"),
        write_s=t.get("write_s"),
    )


def convert_one(path: str, out: str, args: Sequence[str], resume: bool) -> dict[str, Any]:
    """One log: ``slam2world convert PATH -o OUT ARGS --quiet`` and its summary row
    (status ``ok``, ``skipped`` with ``resume`` and complete outputs, or ``error``
    with the exception's class and message). Never raises for a bad log."""
    t0 = time.perf_counter()
    out_dir = Path(out)
    row = _row(path, out_dir, "ok")
    try:
        identity = _identity(path, args)
        if resume and _complete(out_dir, identity):
            row["status"] = "skipped"
            _fill_from_report(row, out_dir)
            return row
        convert_cli(["slam2world", "convert", path, "-o", out, *args, "--quiet"])
        marker = out_dir / MARKER
        tmp = marker.with_name(marker.name + ".tmp")
        tmp.write_text(json.dumps(identity, indent=1))
        os.replace(tmp, marker)
        _fill_from_report(row, out_dir)
    except Exception as e:  # a broken log is a row, never a failed batch
        row.update(status="error", error_class=type(e).__name__, message=str(e))
    row["total_s"] = time.perf_counter() - t0
    return row


def _paths_of(paths: Iterable[str | os.PathLike[str]] | ray.data.Dataset) -> list[str]:
    """The inputs as strings; a Ray Dataset gives its ``path`` column (or its only one)."""
    cls = type(paths)
    if cls.__name__ in ("Dataset", "MaterializedDataset") and cls.__module__.startswith("ray."):
        columns = paths.columns() or []  # type: ignore[union-attr]
        if "path" in columns:
            column = "path"
        elif len(columns) == 1:
            column = columns[0]
        else:
            raise ValueError(
                "convert_many: a Dataset of paths needs a 'path' column (or one column), "
                f"got {columns}"
            )
        return [str(r[column]) for r in paths.iter_rows()]  # type: ignore[union-attr]
    if isinstance(paths, (str, os.PathLike)):
        return [os.fspath(paths)]
    return [os.fspath(p) for p in paths]


class _Progress:
    """A one-line bar on stderr, drawn only on a terminal."""

    def __init__(self, total: int, enabled: bool | None) -> None:
        self.total = total
        self.done = 0
        self.failed = 0
        self.t0 = time.perf_counter()
        self.enabled = sys.stderr.isatty() if enabled is None else enabled

    def step(self, row: Mapping[str, Any]) -> None:
        self.done += 1
        self.failed += row["status"] == "error"
        if not self.enabled:
            return
        width = 30
        fill = width * self.done // max(self.total, 1)
        elapsed = time.perf_counter() - self.t0
        sys.stderr.write(
            f"\r[{'#' * fill}{'.' * (width - fill)}] {self.done}/{self.total} logs, "
            f"{self.failed} failed ({elapsed:.0f} s)"
        )
        if self.done == self.total:
            sys.stderr.write("\n")
        sys.stderr.flush()


def _write_summary(rows: list[dict[str, Any]], out_dir: Path) -> None:
    """``summary.parquet`` and ``summary.csv``, each through a temporary name."""
    import pyarrow as pa  # type: ignore[import-untyped]
    import pyarrow.parquet as pq  # type: ignore[import-untyped]

    types = {
        "scale": pa.float64(),
        "rmse": pa.float64(),
        "pairs": pa.int64(),
        "keyframes": pa.int64(),
        "points": pa.int64(),
        "octree_leaves": pa.int64(),
        "read_s": pa.float64(),
        "align_s": pa.float64(),
        "backproject_s": pa.float64(),
        "write_s": pa.float64(),
        "total_s": pa.float64(),
    }
    schema = pa.schema([(c, types.get(c, pa.string())) for c in COLUMNS])
    table = pa.Table.from_pylist([{c: r[c] for c in COLUMNS} for r in rows], schema=schema)
    for name, write in (
        ("summary.parquet", lambda p: pq.write_table(table, p)),
        ("summary.csv", lambda p: _write_csv(rows, p)),
    ):
        final = out_dir / name
        tmp = final.with_name(f".{name}.tmp")
        write(tmp)
        os.replace(tmp, final)


def _write_csv(rows: list[dict[str, Any]], path: Path) -> None:
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=COLUMNS, extrasaction="ignore")
        w.writeheader()
        for r in rows:
            w.writerow({c: "" if r[c] is None else r[c] for c in COLUMNS})


def convert_many(
    paths: Iterable[str | os.PathLike[str]] | ray.data.Dataset,
    out_dir: str | os.PathLike[str],
    *,
    options: Mapping[str, Any] | Sequence[str] | None = None,
    address: str | None = None,
    workers: int | None = None,
    resume: bool = False,
    progress: bool | None = None,
) -> list[dict[str, Any]]:
    """Converts every log of ``paths`` (paths, or a Ray Dataset with a ``path``
    column) into ``out_dir/<log stem>/``, one Ray task per log, and writes
    ``out_dir/summary.parquet`` and ``.csv``; returns the rows in input order.

    ``options``: convert options, as command-line arguments (``["--octree",
    "0.2"]``) or a mapping (``{"octree": 0.2}``). ``address``: ``None`` starts
    Ray on this machine (unless one is running in this process), else the
    cluster to join (``"auto"``, ``"ray://host:10001"``). ``workers``: logs
    converted at once (default: as many as Ray has CPUs; locally it also
    sizes the Ray started). ``resume``: skip logs whose outputs are complete.
    ``progress``: the bar on stderr (default: when stderr is a terminal).

    Errors: :class:`ImportError` naming ``pip install 'slam2world[ray]'``
    when Ray is missing; :class:`ValueError` for a bad ``workers`` or
    options; never for one log that fails (its row says why).
    """
    if workers is not None and workers < 1:
        raise ValueError(f"workers must be at least 1, got {workers}")
    args = _option_args(options)
    inputs = _paths_of(paths)
    ray = _import_ray()
    root = Path(out_dir)
    root.mkdir(parents=True, exist_ok=True)
    outs = [str(root / s) for s in _stems(inputs)]
    if not ray.is_initialized():
        if address is None:
            ray.init(num_cpus=workers, include_dashboard=False, log_to_driver=False)
        else:
            ray.init(address=address, log_to_driver=False)
    task = ray.remote(num_cpus=1, max_retries=0)(convert_one)
    limit = workers or max(1, int(ray.available_resources().get("CPU", 1)))
    bar = _Progress(len(inputs), progress)
    rows: list[dict[str, Any] | None] = [None] * len(inputs)
    pending: dict[Any, int] = {}
    queue = list(range(len(inputs)))
    while queue or pending:
        while queue and len(pending) < limit:
            i = queue.pop(0)
            pending[task.remote(inputs[i], outs[i], args, resume)] = i
        ready, _ = ray.wait(list(pending), num_returns=1)
        for ref in ready:
            i = pending.pop(ref)
            try:
                row = ray.get(ref)
            except Exception as e:  # the task itself died (a worker lost): still a row
                row = _row(inputs[i], Path(outs[i]), "error")
                row.update(error_class=type(e).__name__, message=str(e))
            rows[i] = row
            bar.step(row)
    done = [r for r in rows if r is not None]
    _write_summary(done, root)
    return done


def main(argv: Sequence[str] | None = None) -> int:
    """``slam2world batch INPUTS... -o OUT [convert options] [--address A] [--workers N]
    [--resume]``: the exit code is 0 when every log converted (or was skipped), 1 when one
    failed."""
    argv = list(sys.argv[1:] if argv is None else argv)
    p = argparse.ArgumentParser(
        prog="slam2world batch",
        usage="slam2world batch INPUTS... -o OUT [convert options] [--address A] "
        "[--workers N] [--resume]",
        description="Convert many logs on Ray (one task per log). The inputs come first; "
        "every option not listed here is passed to `slam2world convert`.",
    )
    p.add_argument("-o", "--output", required=True, help="output folder (OUT/<log stem>/)")
    p.add_argument("--address", help="Ray cluster to join: auto or ray://HOST:PORT")
    p.add_argument("--workers", type=int, help="logs converted at once")
    p.add_argument("--resume", action="store_true", help="skip logs with complete outputs")
    # The inputs are the arguments before the first option: a convert option's
    # value can then never be taken for a log.
    n = next((i for i, a in enumerate(argv) if a.startswith("-")), len(argv))
    inputs, (ns, rest) = argv[:n], p.parse_known_args(argv[n:])
    if not inputs:
        p.error("no inputs (they come before the options)")
    try:
        rows = convert_many(
            inputs,
            ns.output,
            options=rest,
            address=ns.address,
            workers=ns.workers,
            resume=ns.resume,
        )
    except (ImportError, ValueError) as e:
        print(f"slam2world: error: {e}", file=sys.stderr)
        return 1
    failed = [r for r in rows if r["status"] == "error"]
    ok = sum(r["status"] == "ok" for r in rows)
    skipped = sum(r["status"] == "skipped" for r in rows)
    print(
        f"{len(rows)} logs: {ok} converted, {skipped} skipped, {len(failed)} failed; "
        f"summary in {Path(ns.output) / 'summary.parquet'}"
    )
    for r in failed:
        print(f"slam2world: {r['path']}: {r['error_class']}: {r['message']}", file=sys.stderr)
    return 1 if failed else 0
