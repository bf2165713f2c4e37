"""The conveyor of a machine profile (issue 35): what it sends to advance the roll, and
the profiles refused when loaded rather than between two bites."""

from __future__ import annotations

import pytest

from gcode.machine import default_machine, machine_from_dict


def test_each_kind_of_conveyor_advances_the_roll_by_the_length_asked():
    relay = machine_from_dict({"conveyor": {"kind": "relay", "mm_per_s": 100.0}}).conveyor
    assert relay.lines(450.0) == ["M8", "G4 P4.500", "M9"]  # 4.5 s of relay at 100 mm/s
    axis = machine_from_dict({"conveyor": {"kind": "axis", "axis": "B"}}).conveyor
    assert axis.lines(1234.5) == ["G91", "G1 B1234.500 F3000", "G90"]
    command = machine_from_dict({"conveyor": {"kind": "gcode",
                                              "command": "M100 L{mm}; M101"}}).conveyor
    assert command.lines(12.0) == ["M100 L12.000", "M101"]
    with pytest.raises(ValueError, match="no conveyor"):
        default_machine().conveyor.lines(10.0)


@pytest.mark.parametrize("conveyor, message", [
    ({"kind": "belt"}, "kind must be one of"),
    ({"kind": "gcode", "command": "M100"}, "needs command with {mm}"),
    ({"kind": "gcode", "command": "M100 {mm} {x}"}, "command 'M100 {mm} {x}'"),
    ({"kind": "axis", "axis": "Y"}, "must be A, B or C"),
    ({"kind": "relay", "mm_per_s": 0}, "mm_per_s = 0"),
    ({"kind": "relay", "relay_on": " "}, "needs relay_on and relay_off"),
    ({"speed": 3}, "unknown key 'speed' in \\[conveyor\\]"),
])
def test_a_bad_conveyor_is_refused_naming_the_key(conveyor, message):
    with pytest.raises(ValueError, match=message):
        machine_from_dict({"conveyor": conveyor}, "table.toml")
