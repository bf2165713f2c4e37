"""Wallpaper groups, garment model, fit measure, alignment, reshaping and nesting."""
