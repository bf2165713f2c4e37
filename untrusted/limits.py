"""The field's limits on untrusted input: generous for any real shop, small enough that
no file can make the station allocate gigabytes or loop for minutes.

README.md ("Input limits") states the same numbers; change both together.
"""

from __future__ import annotations

MiB = 1 << 20

MAX_JSON_BYTES = 64 * MiB  # FABRIC, PLACEMENT, LAYOUT, garment specs, instances, calibration
MAX_TOML_BYTES = 1 * MiB  # station.toml, machine profiles
MAX_OBJ_BYTES = 1024 * MiB  # a 2 M-face garment with one vt per corner is about 250 MiB
MAX_GCODE_BYTES = 256 * MiB
MAX_DXF_BYTES = 256 * MiB
MAX_IMAGE_BYTES = 256 * MiB
MAX_IMAGE_PIXELS = 100_000_000  # 100 Mpx: a 10k x 10k table photograph
MAX_DEPTH = 32  # JSON/TOML nesting; real files nest at most 6 deep
MAX_INT_DIGITS = 19  # every integer the station reads fits int64

MAX_GARMENT_MM = 10_000.0  # a garment (3D or its pattern) spans at most 10 m
MIN_PATTERN_MM = 1.0  # a sewing pattern narrower than 1 mm is degenerate (scaled UVs)
MAX_FACES = 2_000_000
MAX_PANEL_POINTS = 100_000  # outline points of one piece / keep-out / instance shape
MIN_REPEAT_MM = 1.0  # the print's lattice vectors
MAX_REPEAT_MM = 2_000.0
MAX_DEMAND = 10_000  # copies of one piece in a strip-packing instance
MAX_PIECES = 10_000  # pieces in a layout or placement
# Ordering a piece's marks and notches is quadratic in their number (nearest neighbour
# and 2-opt): 1,000 take about 1 s and 2 s to plan on one core, 2,000 take 4 s and 8 s.
MAX_FEATURES_PER_PIECE = 1_000  # marks, notches or holes of one piece, each
MAX_LAYOUT_FEATURES = 20_000  # marks, notches and holes of a whole layout
MAX_PASSES = 100  # cutting passes per contour
MAX_COORD_MM = 1_000_000.0  # any table or fabric coordinate: 1 km
MAX_REQUEST_BYTES = 64 * 1024  # one line on the control socket
MAX_SOCKET_PATH_BYTES = 107  # sun_path is 108 bytes with the terminating NUL
