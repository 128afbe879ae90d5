"""Makes the Blender add-on's zip, to install like any add-on
(Edit > Preferences > Add-ons > Install…):

    python3 normalfit-py/blender/build_zip.py [OUT.zip]

Default OUT: normalfit_blender.zip in the current folder. The zip holds
the folder normalfit_blender/ (its Python files only), as Blender expects.
The normalfit package itself is installed apart, from its wheel (the
add-on's preferences do it: docs/blender.md).
"""

from __future__ import annotations

import sys
import zipfile
from pathlib import Path

ADDON = Path(__file__).resolve().parent / "normalfit_blender"


def build(out: Path) -> Path:
    files = sorted(p for p in ADDON.glob("*.py"))
    if not files:
        raise SystemExit(f"build_zip.py: no add-on files in {ADDON}")
    partial = out.with_name(out.name + ".part")
    with zipfile.ZipFile(partial, "w", compression=zipfile.ZIP_DEFLATED) as z:
        for path in files:
            z.write(path, f"{ADDON.name}/{path.name}")
    # Whole or not at all: the zip replaces the old one only when complete.
    partial.replace(out)
    return out


def main(argv: list[str]) -> int:
    if len(argv) > 1:
        print(__doc__.strip().splitlines()[0], file=sys.stderr)
        return 2
    out = Path(argv[0]) if argv else Path("normalfit_blender.zip")
    print(build(out))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
