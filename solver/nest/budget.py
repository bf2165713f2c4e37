"""What every nesting stage is handed besides the problem: a progress callback."""

from __future__ import annotations

from collections.abc import Callable

Progress = Callable[[str], None]
