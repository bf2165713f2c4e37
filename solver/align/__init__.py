"""Wallpaper alignment (paper Sec. 4): per piece a rotation and a translation of the
print so that it runs on, or mirrors, across the seams."""
