#!/usr/bin/env python3
"""Writes the installable add-on: BUILD/isk_blender.zip holding
isk_blender/ (the add-on) and isk_blender/vendor/isk/ (the built isk
package: the compiled extension and its Python files), so that Blender needs
nothing else of isk.

    python3 blender/make_zip.py [--build build] [--out build/isk_blender.zip]
"""

import argparse
import pathlib
import sys
import zipfile

HERE = pathlib.Path(__file__).resolve().parent


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--build", default=str(HERE.parent / "build"),
                        help="the CMake build folder (default: build)")
    parser.add_argument("--out", help="the zip (default: BUILD/isk_blender.zip)")
    args = parser.parse_args()
    build = pathlib.Path(args.build)
    out = pathlib.Path(args.out) if args.out else build / "isk_blender.zip"
    package = build / "python" / "isk"
    extensions = sorted(package.glob("_isk*.so"))
    if not extensions:
        sys.exit(f"make_zip.py: no {package}/_isk*.so: build the Python "
                 "module first (cmake --build build --target _isk)")
    addon = HERE / "isk_blender"
    out.parent.mkdir(parents=True, exist_ok=True)
    partial = out.with_name(out.name + ".part")
    with zipfile.ZipFile(partial, "w", zipfile.ZIP_DEFLATED) as archive:
        for path in sorted(addon.glob("*.py")):
            archive.write(path, f"isk_blender/{path.name}")
        for path in sorted(package.iterdir()):
            if path.is_file() and (path.suffix in (".py", ".pyi", ".so")
                                   or path.name == "py.typed"):
                archive.write(path, f"isk_blender/vendor/isk/{path.name}")
    partial.replace(out)
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
