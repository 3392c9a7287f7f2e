"""A row of ``netsim validate``'s table: one result beside its theory and tolerance."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass
class Check:
    item: str
    result: str
    theory: float
    measured: float
    tolerance: float
    unit: str = ""

    @property
    def passed(self) -> bool:
        return bool(abs(self.measured - self.theory) <= self.tolerance)
