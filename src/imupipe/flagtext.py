"""A failed or flagged check of a run, and its text: the whole detail for the summary's details, the finding alone
for its first screen (:attr:`Flag.short`, built by :func:`short_form` from the detail's clauses and the chance
verdict of :func:`imupipe.verdict.chance_failures`)."""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["Flag", "chance_verdict", "clauses", "flag_line", "short_form"]


@dataclass(frozen=True)
class Flag:
    """One failed or flagged check.

    Attributes
    ----------
    sensor : str
    check : str
        ``bound``, ``stationarity``, ``fit adequacy``, ``allan check``, ``lines``, ``outliers``, ``gaps``,
        ``stuck channel``, ``verification``, ``per-axis bound``, ``parameter on boundary``, ``GM re-assigned``.
    where : str
        Curve (dataset/axis), frequency or component.
    detail : str
        What was found.
    severity : str
        ``fail`` (the integrity claim does not hold as stated) or ``flag`` (look at it).
    short : str
        The finding alone, for the first screen (the detail then in full in the sensor's details section); empty:
        the detail in full on the first screen.
    """

    sensor: str
    check: str
    where: str
    detail: str
    severity: str = "flag"
    short: str = ""


def clauses(text: str, sep: str = "; ") -> list[str]:
    """`text` split at each `sep` outside parentheses and brackets (a FLAG's finding, then its context)."""
    out, depth, start, i = [], 0, 0, 0
    while i < len(text):
        ch = text[i]
        depth += (ch in "([") - (ch in ")]")
        if depth == 0 and text.startswith(sep, i):
            out.append(text[start:i])
            start = i = i + len(sep)
            continue
        i += 1
    return out + [text[start:]]


def flag_line(f: Flag, short: bool = False) -> str:
    """``- FLAG <check> [<where>]: <detail>`` (``FAIL`` for a failed check); `short`: the first screen's form, the
    flag's :attr:`Flag.short` where it has one, saying where the detail is in full."""
    text = f"{f.short} (in full: the details, {f.sensor})" if short and f.short else f.detail
    return f"- {'FAIL' if f.severity == 'fail' else 'FLAG'} {f.check}{f' [{f.where}]' if f.where else ''}: {text}"


def chance_verdict(chance: str) -> str:
    """``"; 1 of 15 axes show a line, consistent with chance"`` (or ``..., more than chance gives: ...``): the count
    and the verdict of a chance text of :func:`imupipe.verdict.chance_failures` (``"k of n axes <outcome> at level
    a each; ... P(>= k) = p[; <a finding beyond the level on its own>]: <verdict>"``), without the arithmetic
    between; empty without one."""
    count = chance.strip("; ").partition(" at level ")[0]
    head, _, verdict = chance.partition("P(>= ")[2].partition(": ")
    why = head.partition("; ")[2]  # a finding beyond the level on its own (chance_failures's `beyond`)
    return f"; {count}" + (f", {why}" if why else "") + f", {verdict}" if count and verdict else ""


def short_form(detail: str, chance: str = "", keep: int | None = 1) -> str:
    """A FLAG's first-screen form: its first `keep` clauses (:func:`clauses`; a clause after the first up to its
    first ``": "``; None: the whole detail) and the chance verdict; empty where that is the detail itself."""
    parts = clauses(detail)
    if keep is not None:
        parts = parts[:keep]
        parts[1:] = [clauses(p, ": ")[0] for p in parts[1:]]
    short = "; ".join(parts) + chance_verdict(chance)
    return "" if short == detail else short
