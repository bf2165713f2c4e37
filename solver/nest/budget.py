"""What every nesting stage is handed besides the problem: a deadline and a progress callback.

``--time T`` is a promise: the whole nest (sparrow, the lattice fills, repairs, building
and verifying the layout) ends within about T. A number of seconds given to a stage would
be counted from when that stage starts, so every overrun would add up; a :class:`Deadline`
is one point in time that every stage reads, and shares of it are taken from what is
*left*, so a stage that ran long shrinks the ones after it instead of pushing the end.
"""

from __future__ import annotations

import time
from collections.abc import Callable

Progress = Callable[[str], None]

#: measured cost of building and verifying a layout, per placed piece (s), on plain and
#: printed fabric (the print adds the lattice and grain checks); with a floor for the
#: fixed part. Nesting stops this much before the deadline to leave room for it.
#: verify_layout took 1.2 ms a piece on the 99 shirts, 2.2 ms under a print, at load ~7.
FINISH_PER_PIECE = 0.0015
FINISH_PER_PRINTED_PIECE = 0.0025
FINISH_MIN = 0.05


class Deadline:
    """A point on the monotonic clock; ``clock`` is injectable so tests need not sleep."""

    def __init__(self, seconds: float, *, clock: Callable[[], float] = time.monotonic,
                 end: float | None = None) -> None:
        self.clock = clock
        self.end = clock() + seconds if end is None else end

    def left(self) -> float:
        """Seconds until the deadline (0 once it has passed)."""
        return max(0.0, self.end - self.clock())

    def expired(self) -> bool:
        return self.clock() >= self.end

    def share(self, fraction: float) -> Deadline:
        """A deadline ``fraction`` of the time left from now (never beyond this one)."""
        return Deadline(0.0, clock=self.clock, end=self.clock() + fraction * self.left())

    def within(self, seconds: float) -> Deadline:
        """The earlier of this deadline and ``seconds`` from now."""
        return Deadline(0.0, clock=self.clock, end=min(self.end, self.clock() + seconds))

    def later(self, seconds: float) -> Deadline:
        """This deadline moved ``seconds`` later (time that was not the search's)."""
        return Deadline(0.0, clock=self.clock, end=self.end + seconds)

    def before(self, seconds: float) -> Deadline:
        """This deadline moved ``seconds`` earlier (a reserve for what follows)."""
        return Deadline(0.0, clock=self.clock, end=self.end - seconds)

    def allows(self, seconds: float) -> bool:
        """Whether a step of ``seconds`` started now still ends before the deadline."""
        return self.clock() + seconds <= self.end

    def __repr__(self) -> str:
        return f"Deadline(left={self.left():.3f} s)"


class Pace:
    """The measured duration of a step that cannot be cut, so that one starts only when it
    fits in what is left (the worst of the last ``MEMORY`` steps: the load changes).
    Before the first is measured, ``prior`` (s) stands for it."""

    MEMORY = 8

    def __init__(self, prior: float = 0.0, clock: Callable[[], float] = time.monotonic,
                 ) -> None:
        self.clock = clock
        self.prior = prior
        self.recent: list[float] = []
        self._start = 0.0

    def start(self) -> None:
        self._start = self.clock()

    def stop(self) -> None:
        self.recent = [*self.recent[1 - self.MEMORY:], self.clock() - self._start]

    def step(self) -> float:
        """Seconds one step takes (``prior`` before the first was measured)."""
        return max(self.recent, default=self.prior)

    def fits(self, deadline: Deadline) -> bool:
        return deadline.allows(self.step())


def deadline_of(limit: float | Deadline) -> Deadline:
    """A stage accepts seconds from now (callers outside the nest) or a shared Deadline."""
    return limit if isinstance(limit, Deadline) else Deadline(float(limit))


def finish_reserve(pieces: int, printed: bool = False) -> float:
    """Seconds to keep for building and verifying a layout of ``pieces`` pieces."""
    return FINISH_MIN + (FINISH_PER_PRINTED_PIECE if printed else FINISH_PER_PIECE) * pieces
