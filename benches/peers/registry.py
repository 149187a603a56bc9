"""The row registry of ``benches/compare.py``.

A row compares our function with a peer's on the same input. Its setup takes
the problem size and returns a :class:`Case`: two callables without arguments
that do the same work (inputs are prepared in the setup, not in the
callables), and how many elements each does (the peer may do a part only, when
it is too slow to run whole: rates are compared per element). A setup may raise
:class:`Skip` (a peer or a data file is missing); the row is then listed as
skipped with the reason.

``ratio`` is always ``peer time / our time`` per element (above 1: we are
faster); ``target`` is the smallest acceptable ratio (``1/1.5`` for "within
1.5x of the limit").
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

Thunk = Callable[[], object]


class Skip(Exception):
    """Raised by a setup when its row cannot run here (the reason is shown)."""


@dataclass
class Case:
    """What one row measures at one size."""

    ours: Thunk
    peer: Thunk | None
    ours_work: int
    peer_work: int | None = None
    #: Extra figures for the table's note and the JSON (e.g. memory per leaf).
    extras: dict[str, float] = field(default_factory=dict)
    #: When set, the row compares these two numbers (lower is better) instead of times.
    values: tuple[float, float] | None = None


Setup = Callable[[int], Case]


@dataclass(frozen=True)
class Row:
    """One comparison of an area: ``name`` (what is measured), ``peer`` (against what)."""

    area: str
    name: str
    peer: str
    size: int
    quick_size: int
    smoke_size: int
    setup: Setup
    target: float | None
    target_text: str
    unit: str
    #: Sizes of the cost curve (none: not on a curve).
    curve: tuple[int, ...]
    #: Our side runs on rayon's pool: measured at several thread counts.
    parallel: bool
    #: The issue that sets the target.
    issue: str
    #: What a Case's work counts (default: the size unit).
    work_unit: str


REGISTRY: list[Row] = []

CURVE_SIZES = (10**3, 10**4, 10**5, 10**6, 10**7)


def register(
    area: str,
    name: str,
    *,
    peer: str,
    size: int,
    quick_size: int | None = None,
    smoke_size: int | None = None,
    target: float | None = None,
    target_text: str = "",
    unit: str = "elements",
    curve: tuple[int, ...] = (),
    parallel: bool = True,
    issue: str = "",
    work_unit: str = "",
) -> Callable[[Setup], Setup]:
    """Registers a row; ``target`` is the smallest acceptable ``peer / ours``."""

    def deco(setup: Setup) -> Setup:
        q = quick_size or size
        text = target_text or (f">={target:g}x" if target is not None else "")
        REGISTRY.append(
            Row(
                area,
                name,
                peer,
                size,
                q,
                smoke_size or min(q, 1000),
                setup,
                target,
                text,
                unit,
                curve,
                parallel,
                issue,
                work_unit or unit,
            )
        )
        return setup

    return deco
