"""One headline claim of a paper: the record the catalogue (``drapebench.claims_catalogue``) fills and the
scoreboard (``drapebench.claims``) tests."""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass(frozen=True)
class Claim:
    """One headline claim. ``kind``: "order" (every ``greater`` pair (a, b) has a's ``metric`` above b's in every
    group of ``groups``; a dict maps a group to its own pairs), "order_groups" (``row``'s ``metric`` in group a above
    group b for every ``greater`` pair (a, b)), "level" (``row``'s ``metric`` at most ``bound`` in
    every group), "runs" (``row`` has a number in every group) or "untested" (``why``: what it needs)."""

    id: str
    source: str  # paper, table or figure
    claim: str
    paper: str  # the paper's figures, verbatim
    kind: str
    table: str = ""
    metrics: tuple = ()
    greater: object = ()
    row: str = ""
    bound: float = float("inf")
    groups: tuple = ()
    comparable: bool = True  # False: an absolute level on a scene unlike the paper's (indicative only)
    command: str = ""
    why: str = ""
    notes: tuple = field(default_factory=tuple)
