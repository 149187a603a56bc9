"""Defaults live in one place (`src/defaults.rs`): every default of the native
module's signatures and of the stub equals the Rust constant of the same
parameter name (exported as ``_slam2world.DEFAULTS``), and the stub's defaults
equal the signatures' wherever both give one."""

from __future__ import annotations

import ast
import inspect
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import slam2world._slam2world as native

STUB = Path(native.__file__).with_name("_slam2world.pyi")
if not STUB.exists():  # an installed wheel keeps the stub beside the package
    STUB = Path(__file__).resolve().parents[2] / "python" / "slam2world" / "_slam2world.pyi"


def _stub_defaults() -> dict[str, dict[str, Any]]:
    """`qualified name -> {parameter: default}` of every function in the stub."""
    tree = ast.parse(STUB.read_text())
    out: dict[str, dict[str, Any]] = {}

    def visit(body: list[ast.stmt], prefix: str) -> None:
        for node in body:
            if isinstance(node, ast.ClassDef):
                visit(node.body, prefix + node.name + ".")
            elif isinstance(node, ast.FunctionDef):
                a = node.args
                params = a.posonlyargs + a.args
                pos = dict(
                    zip([p.arg for p in params[len(params) - len(a.defaults) :]], a.defaults)
                )
                kw = {p.arg: d for p, d in zip(a.kwonlyargs, a.kw_defaults) if d is not None}
                found = {}
                for name, d in {**pos, **kw}.items():
                    try:
                        found[name] = ast.literal_eval(d)
                    except ValueError:
                        continue
                name = node.name if node.name != "__new__" else "__init__"
                out[prefix + name] = found

    visit(tree.body, "")
    return out


def _runtime_callables() -> Iterator[tuple[str, Any]]:
    for name, obj in vars(native).items():
        if name.startswith("_"):
            continue
        if inspect.isclass(obj):
            for attr, member in vars(obj).items():
                if callable(member) and (not attr.startswith("_") or attr == "__new__"):
                    yield f"{name}.{attr if attr != '__new__' else '__init__'}", getattr(obj, attr)
            yield f"{name}.__init__", obj
        elif callable(obj):
            yield name, obj


def _runtime_defaults(obj: Any) -> dict[str, Any] | None:
    try:
        sig = inspect.signature(obj)
    except (TypeError, ValueError):
        return None
    return {
        p.name: p.default
        for p in sig.parameters.values()
        if p.default is not inspect.Parameter.empty and p.default is not Ellipsis
    }


def test_the_rust_constants_are_exported() -> None:
    d = native.DEFAULTS
    assert d["max_diff"] == 0.01 and d["loss"] == "huber" and d["prob_hit"] == 0.7
    assert d["imu_initialize.max_gap"] == 0.05 and d["max_gap"] == 0.1
    assert all(isinstance(v, (int, float, str)) for v in d.values())


def _constant(qual: str, param: str) -> tuple[bool, Any]:
    """The Rust default of `param` of the function `qual` (a `function.param`
    entry first: one name can mean another thing in one function)."""
    for key in (f"{qual.split('.')[-1]}.{param}", f"{qual}.{param}", param):
        if key in native.DEFAULTS:
            return True, native.DEFAULTS[key]
    return False, None


def test_signatures_use_the_rust_defaults() -> None:
    checked = 0
    for qual, obj in _runtime_callables():
        got = _runtime_defaults(obj)
        if not got:
            continue
        for param, value in got.items():
            known, want = _constant(qual, param)
            if known:
                assert value == want, f"{qual}({param}={value!r}), the constant is {want!r}"
                checked += 1
    # max_diff alone appears in six signatures.
    assert checked >= 20, checked


def test_stub_defaults_match_the_signatures_and_the_constants() -> None:
    stub = _stub_defaults()
    runtime = dict(_runtime_callables())
    checked = 0
    for qual, defaults in stub.items():
        for param, value in defaults.items():
            known, want = _constant(qual, param)
            if known:
                assert value == want, f"stub {qual}({param}={value!r}), the constant is {want!r}"
                checked += 1
        obj = runtime.get(qual)
        got = _runtime_defaults(obj) if obj is not None else None
        if not got:
            continue
        for param, value in defaults.items():
            if param in got:
                assert got[param] == value, (
                    f"{qual}({param}): stub {value!r}, runtime {got[param]!r}"
                )
    assert checked >= 20, checked
