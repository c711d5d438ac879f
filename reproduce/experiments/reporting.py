"""What every reproduction report shares: the block of target checks and figure saving."""

from __future__ import annotations

from pathlib import Path
from typing import Any


def target_check(id_: str, what: str, paper: str, ours: str, ok: bool, why: str) -> dict:
    """One check of a reproduction: the paper's value beside ours, ``matched`` where ``ok``,
    else ``missed`` with the reason ``why`` (the row :func:`format_checks` prints)."""
    return {
        "id": id_,
        "what": what,
        "paper": paper,
        "ours": ours,
        "status": "matched" if ok else "missed",
        "reason": "" if ok else why,
    }


def format_checks(checks: list[dict]) -> list[str]:
    """The "Targets (theory §12)" block: one line per check with the paper's value beside ours.

    Each check is a dict with ``id``, ``status`` (matched / missed / …), ``what``, ``paper``,
    ``ours`` and ``reason`` (why it was missed, or empty).
    """
    lines = ["", "Targets (theory §12):"]
    for ch in checks:
        tail = f" — {ch['reason']}" if ch["reason"] else ""
        lines.append(
            f"  {ch['id']:<6} {ch['status']:<8} {ch['what']}: paper {ch['paper']}, "
            f"ours {ch['ours']}{tail}"
        )
    return lines


def round_off(value: float, floor: float, spec: str = ".1e") -> str:
    """``value`` as a report prints it: ``< floor`` when ``|value| < floor`` (floating-point
    round-off, whose digits differ between machines' BLAS and SIMD paths, so a report that
    printed them would change from machine to machine), else ``format(value, spec)``. The
    JSON results keep the raw value."""
    return f"< {floor:.0e}" if abs(value) < floor else format(value, spec)


def save_figure(fig: Any, path: Path) -> Path:
    """Lay out, save (120 dpi) and close a matplotlib figure; return its path."""
    import matplotlib.pyplot as plt

    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path
