"""Errors the `station` command reports as one line (exit status 2).

Kept apart from `station.cli` so that ``python -m station.cli`` (where the CLI module runs
as ``__main__``) still catches the very class the commands raise.
"""


class UserError(Exception):
    """A fault in the operator's input: printed as one line, exit status 2."""
