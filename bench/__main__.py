"""Run every benchmark module in `bench/` (each defines ``main() -> None``)."""

import importlib
import pkgutil
import sys

import bench


def run_all(selected: list[str]) -> None:
    for info in sorted(pkgutil.iter_modules(bench.__path__), key=lambda m: m.name):
        if info.name.startswith("_") or (selected and info.name not in selected):
            continue
        module = importlib.import_module(f"bench.{info.name}")
        if hasattr(module, "main"):
            print(f"== bench/{info.name}.py", flush=True)
            module.main()


if __name__ == "__main__":
    run_all(sys.argv[1:])
