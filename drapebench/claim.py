"""One headline claim of a paper: the record each method's ``claims.py`` fills (``drapebench.claims_catalogue``) and
the scoreboard (``drapebench.claims``) tests."""

from __future__ import annotations

from dataclasses import dataclass, field

RUNTIME = ("a drape time measures the method's own operations; its untrained network or a skinning is not an "
           "alternative explanation of it")  # the control_why of a claim on drape time


@dataclass(frozen=True)
class Claim:
    """One headline claim. ``kind``: "order" (every ``greater`` pair (a, b) has a's ``metric`` above b's in every
    group of ``groups``; a dict maps a group to its own pairs), "order_groups" (``row``'s ``metric`` in group a above
    group b for every ``greater`` pair (a, b)), "level" (``row``'s ``metric`` at most ``bound`` in every group),
    "within" (``row``'s ``metric`` in every group at most ``bound`` times its value in group ``reference``) or
    "untested" (``why``: what it needs).

    ``control``: the rows put in place of ``credited`` (the row the claim credits: ``row``, or the lower row of
    every pair), or {row: row} maps of rows put in place of the claim's, to see whether something that is not the
    method meets the claim as well; ``control_why`` says why a claim has none."""

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
    reference: str = ""  # "within": the group the others are compared with
    bound_metric: str = ""  # "level": a metric of the row whose value is added to the bound in each group
    control: tuple = ()
    control_why: str = ""
    credited: str = ""
    comparable: bool = True  # False: an absolute level on a scene unlike the paper's (indicative only)
    why: str = ""
    notes: tuple = field(default_factory=tuple)

    def __post_init__(self):
        """A claim that cannot fail is refused: a "level" or "within" needs a finite ``bound`` (and "within" its
        ``reference`` group), and each of ``groups`` its pairs in a ``greater`` dict; a ValueError names the claim."""
        if self.kind in ("level", "within") and not abs(self.bound) < float("inf"):
            raise ValueError(f"claim {self.id}: a {self.kind!r} claim needs a finite bound= (without one every value holds)")
        if self.kind == "within" and not self.reference:
            raise ValueError(f"claim {self.id}: a 'within' claim needs reference= (the group the others are compared with)")
        if self.groups and isinstance(self.greater, dict) and "*" not in self.greater:
            unpaired = [g for g in self.groups if g not in self.greater]
            if unpaired:  # a group without pairs would be tested on nothing and vanish from the verdict
                raise ValueError(f"claim {self.id}: groups {', '.join(unpaired)} have no pairs in greater= (give them pairs, "
                                 "or a '*' entry for every group)")

    def credited_row(self) -> str:
        """The row the claim credits: ``credited``, ``row``, or the lower row that every ``greater`` pair names."""
        if self.credited or self.row:
            return self.credited or self.row
        pairs = [p for ps in self.greater.values() for p in ps] if isinstance(self.greater, dict) else list(self.greater)
        common = set.intersection(*({b} for _, b in pairs)) if pairs else set()
        if len(common) != 1:
            raise ValueError(f"claim {self.id}: name the row it credits (credited=...): its pairs' lower rows differ")
        return common.pop()
