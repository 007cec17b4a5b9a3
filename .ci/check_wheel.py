"""Checks what `make wheel` built: the wheel installs on glibc 2.17 (its tag, and no versioned
symbol of the extension newer than that), the extension is stripped, the licence files and the
project URLs are in the metadata, and an sdist is beside it. Exits 1 naming what is wrong."""

from __future__ import annotations

import re
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path

OLDEST = (2, 17)


def main(dist: Path) -> int:
    problems: list[str] = []
    wheels = sorted(dist.glob("*.whl"))
    if len(wheels) != 1:
        print(f"expected one wheel in {dist}; found {[w.name for w in wheels]}")
        return 1
    wheel = wheels[0]
    if "manylinux_2_17_x86_64" not in wheel.name:
        problems.append(f"tag: {wheel.name} is not manylinux_2_17")
    if not list(dist.glob("upm-*.tar.gz")):
        problems.append("no sdist beside the wheel")
    with zipfile.ZipFile(wheel) as z, tempfile.TemporaryDirectory() as tmp:
        names = z.namelist()
        for licence in ("LICENSE-MIT", "LICENSE-APACHE"):
            if not any(n.endswith(licence) for n in names):
                problems.append(f"{licence} is not in the wheel")
        meta = z.read(next(n for n in names if n.endswith("METADATA"))).decode()
        if "Project-URL: Repository" not in meta:
            problems.append("no Project-URL in the metadata")
        so = next(n for n in names if n.endswith(".so"))
        path = Path(z.extract(so, tmp))
        symbols = subprocess.run(["objdump", "-T", str(path)], capture_output=True, text=True).stdout
        versions = {tuple(int(x) for x in v.split(".")) for v in re.findall(r"GLIBC_(\d+\.\d+)", symbols)}
        newest = max(versions, default=(0, 0))
        if newest > OLDEST:
            problems.append(f"the extension needs GLIBC_{newest[0]}.{newest[1]} (> 2.17)")
        sections = subprocess.run(["objdump", "-h", str(path)], capture_output=True, text=True).stdout
        if ".debug_info" in sections or ".symtab" in sections:
            problems.append("the extension is not stripped")
        size = path.stat().st_size / 1e6
    for p in problems:
        print(f"check_wheel: {p}")
    if not problems:
        print(f"check_wheel: {wheel.name} ok (extension {size:.1f} MB, newest glibc symbol {newest})")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main(Path(sys.argv[1] if len(sys.argv) > 1 else "dist")))
