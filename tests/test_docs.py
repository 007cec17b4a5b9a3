"""The docs' code blocks run as written: each listed page's ```python blocks, in order, in one
namespace (a page is a script a reader pastes). Pages join the list as their blocks become whole."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = {"docs/envs.md": ("gymnasium",), "docs/vision.md": ("cv2",)}  # page: the optional modules it needs


def blocks(page: Path) -> list[str]:
    return re.findall(r"```python\n(.*?)```", page.read_text(), flags=re.S)


@pytest.mark.parametrize("page", sorted(PAGES))
def test_every_block_of_the_page_runs(page, tmp_path, monkeypatch):
    for module in PAGES[page]:
        pytest.importorskip(module)
    code = blocks(ROOT / page)
    assert code, f"{page} has no python block"
    monkeypatch.chdir(tmp_path)
    namespace: dict[str, object] = {"__name__": "__docs__"}
    for k, block in enumerate(code):
        exec(compile(block, f"{page}[{k}]", "exec"), namespace)
