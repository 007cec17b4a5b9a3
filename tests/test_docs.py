"""The docs' code blocks run as written: every ```python block of the README and of each page of
docs/, in order, in one namespace (a page is a script a reader pastes); a page with a block that
is not whole fails. A loop a block runs is cut to a few cycles here: the block shows how to run
it, the benchmarks and the demo tests hold what it achieves."""

from __future__ import annotations

import functools
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: The optional modules a page needs.
NEEDS = {"docs/envs.md": ("gymnasium",), "docs/vision.md": ("cv2",), "docs/viz.md": ("rerun",)}
PAGES = {
    str(page.relative_to(ROOT)): NEEDS.get(str(page.relative_to(ROOT)), ())
    for page in [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
    if "```python" in page.read_text()
}
#: The most cycles a loop in a block runs here.
CYCLES = 12


def test_the_pages_with_blocks_are_found():
    assert {"README.md", "docs/control.md", "docs/envs.md", "docs/polygons.md"} <= set(PAGES)


def _cut(run):
    @functools.wraps(run)
    def cut(self, cycles=CYCLES, *args, **kwargs):
        return run(self, min(int(cycles), CYCLES), *args, **kwargs)

    return cut


def blocks(page: Path) -> list[str]:
    return re.findall(r"```python\n(.*?)```", page.read_text(), flags=re.S)


@pytest.mark.parametrize("page", sorted(PAGES))
def test_every_block_of_the_page_runs(page, tmp_path, monkeypatch):
    for module in PAGES[page]:
        pytest.importorskip(module)
    code = blocks(ROOT / page)
    assert code, f"{page} has no python block"
    monkeypatch.chdir(tmp_path)
    from upm import control

    for loop in (control.Loop, control.PoseLoop):
        monkeypatch.setattr(loop, "run", _cut(loop.run))
    namespace: dict[str, object] = {"__name__": "__docs__"}
    for k, block in enumerate(code):
        exec(compile(block, f"{page}[{k}]", "exec"), namespace)
