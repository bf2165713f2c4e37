"""A synthetic camera over printed fabric and a GRBL 1.1 emulator, for dry runs and tests."""
