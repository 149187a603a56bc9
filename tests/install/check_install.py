#!/usr/bin/env python3
"""Installs slam2world the way users do and checks that it works there (issue 21).

Run by ``make test-install`` (part of ``make test``) after ``make wheel`` has put the wheel and
the sdist into ``dist/``:

- the wheel: its file list, its metadata and its manylinux tag (``auditwheel show``, glibc <= 2.17);
  installed into a fresh venv with ``cargo`` and ``rustc`` off ``PATH`` (binary packages only),
  then ``slam2world demo`` (reduced) and a short ``slam2world.align`` there, with the source tree
  hidden where the kernel lets us (a private mount namespace with an empty tmpfs over it), and
  ``mypy --strict`` against the installed stub;
- the ``slam2world`` binary built by cargo (the one the integration tests run), copied to an
  empty folder: ``simulate``, ``convert`` and ``demo`` there, nothing read from the source
  tree, no libpython linked;
- the sdist: built and installed by pip in another fresh venv (this one compiles, with cargo),
  then the same short use.

Each check prints one line; the last line is ``install check: N passed, N failed``. The exit
status is 1 when any check failed. Temporary venvs go to a temporary folder (``--keep`` keeps it).
"""

from __future__ import annotations

import argparse
import email.parser
import json
import os
import re
import resource
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import traceback
import zipfile
from collections.abc import Callable, Sequence
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
VERSION_RE = re.compile(r'^version\s*=\s*"([^"]+)"', re.MULTILINE)
# The oldest glibc the wheel may require: manylinux2014 (see the Makefile's MANYLINUX).
MAX_GLIBC = (2, 17)
# No file of the sdist is larger (the biggest today: Cargo.lock, 45 kB).
SDIST_FILE_MAX = 1 << 20
# Reduced sizes: the full demo is the job of `make demo`, not of this check.
DEMO_ARGS = ["demo", "-o", "demo", "--reduced", "8", "--no-plots"]

SHORT_USE = r"""
import sys
from pathlib import Path

import numpy as np

import slam2world as s2w

prefix = Path(sys.prefix).resolve()
where = Path(s2w.__file__).resolve()
assert prefix in where.parents, f"slam2world imported from {where}, not from {prefix}"
assert s2w.__version__ == sys.argv[1], (s2w.__version__, sys.argv[1])

rng = np.random.default_rng(7)
source = rng.normal(size=(200, 3))
q = np.array([0.2, -0.4, 0.1, 0.9])
truth = s2w.Sim3.from_quaternion(q / np.linalg.norm(q), [1.0, -2.0, 0.5], 3.7)
target = truth.apply(source)
fit = s2w.align(source, target)
assert abs(fit.transform.scale - 3.7) < 1e-9, fit.transform.scale
np.testing.assert_allclose(fit.transform.matrix(), truth.matrix(), atol=1e-9)
assert fit.rmse < 1e-9, fit.rmse
assert fit.residuals.shape == (200,)
try:
    s2w.align(source[:2], target[:2])
except s2w.Slam2WorldError as e:
    assert isinstance(e, ValueError), type(e)
else:
    raise AssertionError("two pairs were accepted")
print(f"align: scale {fit.transform.scale:.12f}, rmse {fit.rmse:.2e}, from {where.parent}")
"""

# mypy --strict must accept this against the installed stub (py.typed found, names typed) ...
TYPED_OK = """
import numpy as np
import numpy.typing as npt

import slam2world as s2w

points: npt.NDArray[np.float64] = np.zeros((4, 3))
fit: s2w.Alignment = s2w.align(points, points + 1.0, scale=False)
scale: float = fit.transform.scale
moved: npt.NDArray[np.float32] = fit.transform.apply(points.astype(np.float32))
"""
# ... and reject this, which it can only do when the stub (not Any) gives the types.
TYPED_BAD = """
import numpy as np

import slam2world as s2w

rmse: str = s2w.align(np.zeros((4, 3)), np.zeros((4, 3))).rmse
"""
TYPED_BAD_MESSAGE = 'expression has type "float", variable has type "str"'


class CheckFailed(Exception):
    """A check found the installed package wrong (the message says what and where)."""


def run(
    cmd: Sequence[str | Path],
    *,
    cwd: Path | None = None,
    env: dict[str, str] | None = None,
    timeout: float = 1800.0,
) -> str:
    """Runs ``cmd`` in a process group of its own; its stdout and stderr, or CheckFailed with
    their tail. Past ``timeout`` seconds the whole group is killed (cargo's rustc too)."""
    args = [str(c) for c in cmd]
    proc = subprocess.Popen(
        args,
        cwd=cwd,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        start_new_session=True,
    )
    try:
        out, _ = proc.communicate(timeout=timeout)
    except BaseException as e:  # the time limit, or Ctrl-C: leave nothing running
        os.killpg(proc.pid, signal.SIGKILL)
        proc.communicate()
        if isinstance(e, subprocess.TimeoutExpired):
            raise CheckFailed(f"{' '.join(args)}: no answer in {timeout:.0f} s") from e
        raise
    if proc.returncode != 0:
        tail = "\n".join(out.splitlines()[-25:])
        raise CheckFailed(f"{' '.join(args)} exited {proc.returncode}:\n{tail}")
    return out


def without_rust_env() -> dict[str, str]:
    """This environment with every PATH entry holding cargo or rustc removed, and no CARGO_*."""
    env = {k: v for k, v in os.environ.items() if not k.startswith(("CARGO", "RUSTUP", "RUSTC"))}
    keep = [
        d
        for d in os.environ.get("PATH", "").split(os.pathsep)
        if d and not any(Path(d, tool).exists() for tool in ("cargo", "rustc"))
    ]
    env["PATH"] = os.pathsep.join(keep)
    for tool in ("cargo", "rustc"):
        if shutil.which(tool, path=env["PATH"]) is not None:
            raise CheckFailed(f"{tool} still on the stripped PATH {env['PATH']}")
    env.pop("VIRTUAL_ENV", None)
    env.pop("SLAM2WORLD_PYTHON", None)
    return env


class Hider:
    """Runs commands with the source tree hidden (an empty tmpfs over it, in a private mount
    namespace), when ``unshare`` is allowed here; otherwise runs them as they are."""

    def __init__(self, tree: Path) -> None:
        self.tree = tree
        probe = [
            "unshare",
            "--mount",
            "--propagation",
            "private",
            "--",
            "sh",
            "-c",
            'mount -t tmpfs none "$0" && test -z "$(ls -A "$0")"',
            str(tree),
        ]
        try:
            ok = subprocess.run(probe, capture_output=True, timeout=30, check=False)
            self.active = ok.returncode == 0
        except (OSError, subprocess.TimeoutExpired):
            self.active = False

    def wrap(self, cmd: Sequence[str | Path]) -> list[str | Path]:
        """``cmd``, run with the source tree hidden where possible."""
        if not self.active:
            return list(cmd)
        return [
            "unshare",
            "--mount",
            "--propagation",
            "private",
            "--",
            "sh",
            "-c",
            'mount -t tmpfs none "$0" && exec "$@"',
            str(self.tree),
            *cmd,
        ]

    def note(self) -> str:
        return (
            f"source tree {self.tree} hidden"
            if self.active
            else "source tree left visible (unshare not allowed here)"
        )


def children_cpu() -> float:
    """User + system CPU seconds of the finished child processes (timings that load spares)."""
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


class Checker:
    """Runs named checks, prints one line each, counts them."""

    def __init__(self) -> None:
        self.passed = 0
        self.failed: list[str] = []

    def check(self, name: str, fn: Callable[[], str]) -> bool:
        t0, cpu0 = time.monotonic(), children_cpu()
        try:
            detail = fn()
        except CheckFailed as e:
            self.failed.append(name)
            print(f"FAIL {name} ({time.monotonic() - t0:.1f} s): {e}", flush=True)
            return False
        except Exception:  # a bug in this script or an unexpected state: report, go on
            self.failed.append(name)
            print(f"FAIL {name}: unexpected error\n{traceback.format_exc()}", flush=True)
            return False
        self.passed += 1
        wall, cpu = time.monotonic() - t0, children_cpu() - cpu0
        print(f"ok   {name} ({wall:.1f} s, {cpu:.1f} s CPU): {detail}", flush=True)
        return True


def one(dist: Path, pattern: str) -> Path:
    found = sorted(dist.glob(pattern))
    if len(found) != 1:
        raise CheckFailed(f"expected one {pattern} in {dist}, found {[p.name for p in found]}")
    return found[0]


def check_wheel_files(wheel: Path, version: str) -> str:
    """The wheel holds the package, the native module, the stub, py.typed, the console script
    and the licences, and nothing else (no tests, no data)."""
    tag = f"slam2world-{version}-cp39-abi3-"
    if not wheel.name.startswith(tag) or "manylinux" not in wheel.name:
        raise CheckFailed(f"{wheel.name}: expected {tag}manylinux_..._x86_64.whl")
    with zipfile.ZipFile(wheel) as z:
        names = set(z.namelist())
        info = f"slam2world-{version}.dist-info"
        needed = {
            "slam2world/__init__.py",
            "slam2world/cli.py",
            "slam2world/plot.py",
            "slam2world/py.typed",
            "slam2world/_slam2world.pyi",
            "slam2world/_slam2world.abi3.so",
            f"{info}/METADATA",
            f"{info}/WHEEL",
            f"{info}/RECORD",
            f"{info}/entry_points.txt",
            f"{info}/licenses/LICENSE-MIT",
            f"{info}/licenses/LICENSE-APACHE",
        }
        missing = needed - names
        if missing:
            raise CheckFailed(f"missing from the wheel: {sorted(missing)}")
        # Beside those: pure-Python modules of the package, and maturin's SBOM of the crates.
        allowed = re.compile(rf"slam2world/\w+\.py|{re.escape(info)}/sboms/[\w.-]+\.json")
        extra = sorted(n for n in names - needed if not allowed.fullmatch(n))
        if extra:
            raise CheckFailed(f"unexpected files in the wheel: {extra}")
        entry = z.read(f"{info}/entry_points.txt").decode()
        if not re.search(r"^slam2world\s*=\s*slam2world\.cli:main$", entry, re.MULTILINE):
            raise CheckFailed(f"no slam2world console script in entry_points.txt:\n{entry}")
        wheel_meta = z.read(f"{info}/WHEEL").decode()
        if "Root-Is-Purelib: false" not in wheel_meta:
            raise CheckFailed(f"WHEEL says the package is pure:\n{wheel_meta}")
        so = z.getinfo("slam2world/_slam2world.abi3.so").file_size
    size = wheel.stat().st_size
    return f"{len(names)} files, wheel {size / 2**20:.2f} MiB, native module {so / 2**20:.2f} MiB"


def check_metadata(wheel: Path, version: str) -> str:
    """Summary, licence expression and files, Requires-Python, classifiers, extras, no URLs."""
    with zipfile.ZipFile(wheel) as z:
        raw = z.read(f"slam2world-{version}.dist-info/METADATA").decode()
    meta = email.parser.Parser().parsestr(raw)
    want = {
        "Name": "slam2world",
        "Version": version,
        "Requires-Python": ">=3.9",
        "License-Expression": "MIT OR Apache-2.0",
    }
    wrong = {k: meta.get(k) for k, v in want.items() if meta.get(k) != v}
    if wrong:
        raise CheckFailed(f"metadata fields {wrong}, expected {want}")
    if float(meta.get("Metadata-Version", "0")) < 2.4:
        raise CheckFailed(f"Metadata-Version {meta.get('Metadata-Version')} < 2.4 (PEP 639)")
    if len(meta.get("Summary", "")) < 20:
        raise CheckFailed(f"summary too short: {meta.get('Summary')!r}")
    if sorted(meta.get_all("License-File", [])) != ["LICENSE-APACHE", "LICENSE-MIT"]:
        raise CheckFailed(f"License-File: {meta.get_all('License-File')}")
    extras = set(meta.get_all("Provides-Extra", []))
    if not {"plot", "ray"} <= extras:
        raise CheckFailed(f"extras {sorted(extras)} lack plot or ray")
    requires = meta.get_all("Requires-Dist", [])
    if not any(r.startswith("numpy") and "extra" not in r for r in requires):
        raise CheckFailed(f"numpy is not a plain requirement: {requires}")
    classifiers = meta.get_all("Classifier", [])
    for c in ("Typing :: Typed", "Programming Language :: Rust"):
        if c not in classifiers:
            raise CheckFailed(f"classifier {c!r} missing")
    if any(c.startswith("License ::") for c in classifiers):
        raise CheckFailed("a License :: classifier beside License-Expression (PEP 639 forbids it)")
    if meta.get_all("Project-URL") or meta.get("Home-page"):
        raise CheckFailed("project URLs present: none is published yet")
    readme = str(meta.get_payload())
    if not meta.get("Description-Content-Type", "").startswith("text/markdown") or (
        "make demo" not in readme
    ):
        raise CheckFailed("the README is not the long description")
    return f"{len(classifiers)} classifiers, extras {sorted(extras)}"


def check_auditwheel(py: Path, wheel: Path) -> str:
    """auditwheel show: consistent with manylinux_2_X, X <= 17; no external libraries."""
    out = run([py, "-m", "auditwheel", "show", wheel])
    flat = " ".join(out.split())
    m = re.search(
        r'consistent with the following platform tag: "manylinux_(\d+)_(\d+)_x86_64"', flat
    )
    if m is None:
        raise CheckFailed(f"auditwheel gave no manylinux tag:\n{out}")
    glibc = (int(m.group(1)), int(m.group(2)))
    if glibc > MAX_GLIBC:
        raise CheckFailed(f"needs glibc {glibc}, above {MAX_GLIBC}:\n{out}")
    if "external shared libraries are required" in flat:
        raise CheckFailed(f"the native module needs libraries outside the manylinux set:\n{out}")
    return f"manylinux_{glibc[0]}_{glibc[1]}_x86_64"


def elf_report(path: Path) -> tuple[list[str], list[str]]:
    """(DT_NEEDED entries, debug sections) of an ELF file (pyelftools, auditwheel's own reader)."""
    from elftools.elf.dynamic import DynamicSection
    from elftools.elf.elffile import ELFFile

    with path.open("rb") as f:
        elf = ELFFile(f)
        needed = [
            str(tag.needed)  # type: ignore[attr-defined]  # set by pyelftools on DT_NEEDED tags
            for sec in elf.iter_sections()
            if isinstance(sec, DynamicSection)
            for tag in sec.iter_tags("DT_NEEDED")
        ]
        debug = [s.name for s in elf.iter_sections() if s.name.startswith((".debug", ".zdebug"))]
    return needed, debug


def check_stripped(wheel: Path, tmp: Path) -> str:
    """The native module carries no debug information and links no libpython (abi3)."""
    so = tmp / "_slam2world.abi3.so"
    with zipfile.ZipFile(wheel) as z:
        so.write_bytes(z.read("slam2world/_slam2world.abi3.so"))
    needed, debug = elf_report(so)
    if debug:
        raise CheckFailed(f"debug sections in the native module: {debug}")
    if any(n.startswith("libpython") for n in needed):
        raise CheckFailed(f"the abi3 module links {needed}")
    return f"no debug sections; needs {needed}"


def make_venv(base_python: str, where: Path, env: dict[str, str]) -> Path:
    run([base_python, "-m", "venv", where], env=env)
    return where / "bin" / "python"


def check_wheel_install(
    base_python: str, wheel: Path, tmp: Path, env: dict[str, str], hider: Hider
) -> str:
    """pip installs the wheel (binary packages only, no cargo on PATH) into a fresh venv."""
    py = make_venv(base_python, tmp / "venv-wheel", env)
    run([py, "-m", "pip", "install", "--quiet", "--only-binary=:all:", wheel], env=env, cwd=tmp)
    run([py, "-m", "pip", "check"], env=env, cwd=tmp)
    return f"{py.parent.parent} ({hider.note()})"


def check_demo(venv: Path, tmp: Path, env: dict[str, str], hider: Hider) -> str:
    """``slam2world demo`` (the console script of the venv) in an empty folder."""
    work = tmp / "demo-wheel"
    work.mkdir()
    out = run(hider.wrap([venv / "bin" / "slam2world", *DEMO_ARGS]), cwd=work, env=env)
    return demo_result(work / "demo", out)


def demo_result(folder: Path, out: str) -> str:
    for f in ("demo.json", "world.mcap", "cloud.ply", "report.json", "sim.mcap"):
        if not (folder / f).is_file() or (folder / f).stat().st_size < 100:
            raise CheckFailed(f"demo wrote no {f} into {folder}:\n{out}")
    report = json.loads((folder / "demo.json").read_text())
    err = report["transform_error"]["scale_error"]
    if not abs(err) < 5e-3:
        raise CheckFailed(f"demo scale error {err} (reduced run, expected < 0.5 %)")
    return f"scale error {100 * err:+.3f} %"


def check_short_use(py: Path, version: str, tmp: Path, env: dict[str, str], hider: Hider) -> str:
    """``import slam2world; slam2world.align(...)`` recovers a known Sim(3) exactly."""
    script = tmp / "short_use.py"
    script.write_text(SHORT_USE)
    out = run(hider.wrap([py, script, version]), cwd=tmp, env=env)
    return out.strip().splitlines()[-1]


def check_mypy(dev_py: Path, venv_py: Path, tmp: Path) -> str:
    """mypy --strict with the fresh venv's packages: accepts typed use, rejects a wrong type."""
    good, bad = tmp / "typed_ok.py", tmp / "typed_bad.py"
    good.write_text(TYPED_OK)
    bad.write_text(TYPED_BAD)
    base: list[str | Path] = [
        dev_py,
        "-m",
        "mypy",
        "--strict",
        "--cache-dir",  # fresh (nothing from the source tree), shared by the two runs
        tmp / "mypy-cache",
        "--python-executable",
        venv_py,
    ]
    run([*base, good], cwd=tmp)
    try:
        run([*base, bad], cwd=tmp)
    except CheckFailed as e:
        if TYPED_BAD_MESSAGE not in str(e):
            raise CheckFailed(f"mypy rejected typed_bad.py for another reason: {e}") from e
    else:
        raise CheckFailed("mypy accepted a float assigned to str: the stub is not in use")
    return "typed_ok.py accepted, typed_bad.py rejected (float is not str)"


def cargo_binary() -> Path:
    """The `slam2world` binary that cargo builds for the integration tests (`cargo test`).

    It is the one `make test` has built already: `cargo build --bin` would resolve the
    dependencies' features without the dev-dependencies' and compile the crate and part of
    its dependencies once more (the release wheel's build covers that resolution).
    """
    out = run(
        ["cargo", "test", "--no-run", "--test", "it", "--message-format=json-render-diagnostics"],
        cwd=REPO,
        timeout=3600,
    )
    for line in out.splitlines():
        if line.startswith("{"):
            msg = json.loads(line)
            if msg.get("reason") == "compiler-artifact" and msg.get("executable"):
                target = msg["target"]
                if target["name"] == "slam2world" and target["kind"] == ["bin"]:
                    return Path(msg["executable"])
    raise CheckFailed(f"cargo test --no-run reported no slam2world executable:\n{out[-2000:]}")


def check_binary_copy(tmp: Path, env: dict[str, str], hider: Hider) -> str:
    """The cargo-built binary, copied to an empty folder: simulate, convert, demo run there."""
    exe = tmp / "bin" / "slam2world"
    exe.parent.mkdir()
    shutil.copy2(cargo_binary(), exe)
    needed, _ = elf_report(exe)
    if any(n.startswith("libpython") for n in needed):
        raise CheckFailed(f"the binary links {needed}")
    work = tmp / "demo-bin"
    work.mkdir()
    run(hider.wrap([exe, "simulate", "-o", "sim.mcap", "--reduced", "8"]), cwd=work, env=env)
    run(hider.wrap([exe, "convert", "sim.mcap", "-o", "conv"]), cwd=work, env=env)
    if not (work / "conv" / "report.json").is_file():
        raise CheckFailed(f"convert wrote no report.json into {work / 'conv'}")
    out = run(hider.wrap([exe, *DEMO_ARGS]), cwd=work, env=env)
    return f"{demo_result(work / 'demo', out)}; needs {needed}"


def check_sdist(base_python: str, sdist: Path, version: str, tmp: Path, hider: Hider) -> str:
    """pip builds the sdist from scratch (cargo, maturin from PyPI) and installs it."""
    with tempfile.TemporaryDirectory() as d:
        shutil.unpack_archive(sdist, d)
        top = Path(d) / f"slam2world-{version}"
        for f in ("Cargo.toml", "Cargo.lock", "pyproject.toml", "LICENSE-MIT", "LICENSE-APACHE"):
            if not (top / f).is_file():
                raise CheckFailed(f"{f} missing from {sdist.name}")
        # The repository's own small fixtures may ride along (tests/data); real data sets, build
        # outputs or a virtual environment may not.
        big = [p for p in top.rglob("*") if p.is_file() and p.stat().st_size > SDIST_FILE_MAX]
        if big:
            raise CheckFailed(f"files over {SDIST_FILE_MAX} bytes in the sdist: {big[:5]}")
        stray = [d for d in ("target", ".venv", "dist") if (top / d).exists()]
        if stray:
            raise CheckFailed(f"build folders in the sdist: {stray}")
    env = dict(os.environ)
    env.pop("VIRTUAL_ENV", None)
    # The check asks whether the sdist holds all it needs to build and whether what it builds
    # works, not how fast it runs: maturin builds the sdist's copy of the crate (another path,
    # so always compiled anew) in the dev profile, in the repository's target folder, where the
    # registry dependencies that `cargo test` compiled in that profile are used again.
    env["CARGO_TARGET_DIR"] = str(REPO / "target")
    env["MATURIN_PEP517_ARGS"] = "--profile dev"
    py = make_venv(base_python, tmp / "venv-sdist", env)
    t0 = time.monotonic()
    run([py, "-m", "pip", "install", "--quiet", sdist], env=env, cwd=tmp, timeout=3600)
    build_s = time.monotonic() - t0
    use = check_short_use(py, version, tmp, without_rust_env(), hider)
    size = sdist.stat().st_size / 1024
    return f"sdist {size:.0f} kB, built and installed in {build_s:.0f} s; {use}"


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    ap.add_argument("--dist", type=Path, default=REPO / "dist", help="folder of wheel and sdist")
    ap.add_argument("--keep", action="store_true", help="keep the temporary folder")
    ap.add_argument("--skip-sdist", action="store_true", help="leave out the sdist build")
    args = ap.parse_args(argv)

    match = VERSION_RE.search((REPO / "pyproject.toml").read_text())
    if match is None:
        print("FAIL no version in pyproject.toml")
        return 1
    version = match.group(1)
    dist = args.dist.resolve()
    dev_py = Path(sys.executable)
    # The interpreter the fresh venvs are made from: the base of this venv.
    base_python = getattr(sys, "_base_executable", None) or sys.executable
    tmp = Path(tempfile.mkdtemp(prefix="slam2world-install-"))
    hider = Hider(REPO)
    c = Checker()
    t0 = time.monotonic()
    try:
        wheel = one(dist, "slam2world-*.whl")
        sdist = one(dist, "slam2world-*.tar.gz")
    except CheckFailed as e:
        print(f"FAIL {e} (run `make wheel` first)")
        return 1
    print(f"install check: {wheel.name}, {sdist.name}; temporary folder {tmp}", flush=True)
    try:
        no_rust = without_rust_env()
        c.check("wheel files", lambda: check_wheel_files(wheel, version))
        c.check("wheel metadata", lambda: check_metadata(wheel, version))
        c.check("auditwheel show", lambda: check_auditwheel(dev_py, wheel))
        c.check("stripped native module", lambda: check_stripped(wheel, tmp))
        venv = tmp / "venv-wheel"
        if c.check(
            "wheel into a fresh venv without cargo",
            lambda: check_wheel_install(base_python, wheel, tmp, no_rust, hider),
        ):
            c.check("wheel: slam2world demo", lambda: check_demo(venv, tmp, no_rust, hider))
            py = venv / "bin" / "python"
            c.check(
                "wheel: import and align",
                lambda: check_short_use(py, version, tmp, no_rust, hider),
            )
            c.check("wheel: mypy against the installed stub", lambda: check_mypy(dev_py, py, tmp))
        c.check("cargo binary copied elsewhere", lambda: check_binary_copy(tmp, no_rust, hider))
        if not args.skip_sdist:
            c.check(
                "sdist built and installed in a fresh venv",
                lambda: check_sdist(base_python, sdist, version, tmp, hider),
            )
    finally:
        if args.keep:
            print(f"kept {tmp}")
        else:
            shutil.rmtree(tmp, ignore_errors=True)
    print(f"install check took {time.monotonic() - t0:.0f} s ({children_cpu():.0f} s CPU)")
    if c.failed:
        print(f"failed: {', '.join(c.failed)}")
    print(f"install check: {c.passed} passed, {len(c.failed)} failed")
    return 1 if c.failed else 0


if __name__ == "__main__":
    sys.exit(main())
