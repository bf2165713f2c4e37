"""Camera access, calibration to table millimetres, lattice and wallpaper-group detection."""
