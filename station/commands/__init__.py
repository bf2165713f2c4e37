"""One module per `station` subcommand.

Each module defines ``register(subparsers)`` which adds its parser and sets
``func`` to a callable ``(args) -> int``. `station.cli` discovers the modules,
so adding a command means adding a file here and nothing else.
"""
