"""GRBL 1.1 response parsing and codes, quoting doc/markdown/interface.md for each form."""

from __future__ import annotations

import pytest

from gcode.grbl import (
    ALARM_CODES,
    ERROR_CODES,
    alarm_message,
    check_settings,
    error_message,
    parse_response,
    parse_settings,
    parse_status,
)
from gcode.machine import default_machine


@pytest.mark.parametrize("line,kind,code,text", [
    ("ok", "ok", None, None),
    ("error:22", "error", 22, None),
    ("ALARM:2", "alarm", 2, None),
    ("Grbl 1.1h ['$' for help]", "banner", None, "1.1h"),
    ("[MSG:'$H'|'$X' to unlock]", "msg", None, "'$H'|'$X' to unlock"),
    ("[MSG:Reset to continue]", "msg", None, "Reset to continue"),
    ("[GC:G0 G54 G17 G21 G90 G94 M0 M5 M9 T0 F0. S0.]", "gc", None,
     "G0 G54 G17 G21 G90 G94 M0 M5 M9 T0 F0. S0."),
    ("[HLP:$$ $# $G $I $N $x=val $Nx=line $J=line $C $X $H ~ ! ? ctrl-x]", "help", None, None),
    ("[VER:1.1h.20190825:]", "ver", None, "1.1h.20190825:"),
    ("[OPT:V,15,128]", "opt", None, "V,15,128"),
    ("[echo:G1X0.540Y10.4F100]", "echo", None, "G1X0.540Y10.4F100"),
    ("[G54:0.000,0.000,0.000]", "param", None, "G54:0.000,0.000,0.000"),
    ("[PRB:0.000,0.000,0.000:0]", "param", None, "PRB:0.000,0.000,0.000:0"),
    ("[TLO:0.000]", "param", None, "TLO:0.000"),
    ("$32=1", "setting", 32, "1"),
    ("$11=0.010", "setting", 11, "0.010"),
    ("$N0=G54", "startup_line", 0, "G54"),
    ("$N1=", "startup_line", 1, ""),
    (">G54G20:ok", "startup_exec", None, "G54G20"),
    (">:error:7", "startup_exec", None, ""),
    ("", "empty", None, None),
    ("o", "unknown", None, None),  # a dropped byte
    ("okok", "unknown", None, None),
    ("<Idle|MPos:1.0,2.0>", "status", None, None),
    ("<Idle|MPos:1.0,2.0", "unknown", None, None),  # truncated report
    ("<Idle>", "unknown", None, None),  # no position: not a GRBL 1.1 report
])
def test_every_response_kind(line, kind, code, text):
    r = parse_response(line)
    assert r.kind == kind
    assert r.code == code
    if text is not None:
        assert r.text == text


def test_status_with_every_optional_field():
    st = parse_status("<Hold:1|MPos:10.000,-2.500,0.000|Bf:15,128|Ln:99|FS:500,8000|"
                      "WCO:1.000,2.000,0.000|Pn:XZP|Ov:120,50,80|A:SFM|Ex:1>")
    assert (st.state, st.substate) == ("Hold", 1)
    assert st.mpos == (10.0, -2.5, 0.0) and st.wco == (1.0, 2.0, 0.0)
    assert (st.planner_free, st.rx_free, st.line_number) == (15, 128, 99)
    assert (st.feed, st.speed) == (500.0, 8000.0)
    assert st.pins == "XZP" and st.overrides == (120, 50, 80) and st.accessories == "SFM"
    assert st.extra == {"Ex": "1"}
    w = parse_status("<Run|WPos:-2.500,0.000,11.000|F:500|WCO:1,1,1>")
    assert w.feed == 500.0 and w.speed is None
    # "WPos = MPos - WCO" (interface.md)
    assert w.position() == (-1.5, 1.0, 12.0)
    assert parse_status("<Door:2|MPos:0,0,0>").substate == 2


def test_code_tables_match_the_grbl_csv():
    # error codes 1-38 without 18, 19 (doc/csv/error_codes_en_US.csv), alarms 1-9
    assert sorted(ERROR_CODES) == [c for c in range(1, 39) if c not in (18, 19)]
    assert sorted(ALARM_CODES) == list(range(1, 10))
    assert error_message(22) == ("error:22 Undefined feed rate: Feed rate has not yet been set "
                                 "or is undefined.")
    assert alarm_message(2).startswith("ALARM:2 Soft limit: Soft limit alarm.")
    assert "Unknown" in error_message(99) and "Unknown" in alarm_message(42)
    assert parse_response("error:9").message.endswith("locked out during alarm or jog state.")


def test_settings_checked_against_the_profile():
    lines = ["$0=10", "$13=0", "$30=1000", "$32=1", "$110=12000.000", "$111=12000.000",
             "$130=1600.000", "$131=1000.000", "ok"]
    s = parse_settings(lines)
    assert s[110] == 12000.0 and 0 in s and len(s) == 8
    assert check_settings(s, default_machine()) == []
    bad = {**s, 32: 0, 30: 255, 131: 200.0, 13: 1}
    faults = check_settings(bad, default_machine())
    assert len(faults) == 4
    assert any("$32 laser mode is off" in f for f in faults)
    assert any("$131 Y maximum travel 200" in f for f in faults)
    # the feed watchdog times acceleration with the profile's: a slower controller is refused
    slow = check_settings({**s, 120: 10.0, 121: 1500.0}, default_machine())
    assert slow == ["$120 X acceleration 10 mm/s^2 is below the profile's acceleration 1500 "
                    "(the feed watchdog expects the programmed feed within that acceleration "
                    "time)"]
