"""Faults injected into an emulated GRBL and the wire to it: lost, flipped, doubled or inserted
bytes in either direction, errors, alarms, resets, disconnections and power cuts at chosen
lines, and lost or doubled `ok`s."""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass
class Faults:
    """Faults to inject. Lines count from 1 over every line the machine receives (including `$`
    commands and empty lines); bytes count from 1 over every byte written to it."""

    error_at: dict[int, int] = field(default_factory=dict)  # line -> error code
    alarm_at: dict[int, int] = field(default_factory=dict)  # line -> alarm code
    drop_byte_at: set[int] = field(default_factory=set)
    flip_byte_at: set[int] = field(default_factory=set)  # XOR 0x01 (e.g. '1' <-> '0')
    reset_at: set[int] = field(default_factory=set)
    disconnect_at: set[int] = field(default_factory=set)
    power_cut_at: set[int] = field(default_factory=set)
    dup_byte_at: set[int] = field(default_factory=set)  # the byte arrives twice
    insert_at: dict[int, bytes] = field(default_factory=dict)  # a burst before byte N
    # The controller's transmit line (GRBL -> host): bytes count from 1 over every byte it
    # sends; and its answers: `ok`s count from 1 over every `ok` it sends.
    out_drop_at: set[int] = field(default_factory=set)
    out_flip_at: set[int] = field(default_factory=set)
    out_dup_at: set[int] = field(default_factory=set)
    out_insert_at: dict[int, bytes] = field(default_factory=dict)
    drop_ok_at: set[int] = field(default_factory=set)
    dup_ok_at: set[int] = field(default_factory=set)

    def corrupt(self, data: bytes, first: int, drop: set[int], flip: set[int],
                dup: set[int], insert: dict[int, bytes]) -> bytes:
        """``data`` as a faulty line delivers it, its first byte being number ``first``.
        WHY one routine: both directions of the wire fail the same ways."""
        last = first + len(data)
        if not any(first <= n < last for f in (drop, flip, dup, insert) for n in f):
            return data
        out = bytearray()
        for n, byte in enumerate(data, first):
            out += insert.get(n, b"")
            if n in drop:
                continue
            byte ^= 0x01 if n in flip else 0
            out += bytes([byte, byte]) if n in dup else bytes([byte])
        return bytes(out)
