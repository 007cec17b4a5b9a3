"""The demo and the examples run and print what they promise."""

import runpy
import subprocess
import sys
from pathlib import Path

import pytest

from upm import cli

ROOT = Path(__file__).resolve().parents[1]


def test_demo_prints_the_table_with_the_optimum(tmp_path, capsys):
    assert cli.main(["demo", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "b = 0.500, phi = 0.500 pi, v_eq = 0.500000" in out
    # The starred cell of the feed-rate table is (b, phi) = (1/2, pi/2).
    starred = [line for line in out.splitlines() if "0.5000*" in line]
    assert len(starred) == 1
    assert starred[0].startswith("0.500 ")
    assert (tmp_path / "fig3_6.png").stat().st_size > 10_000
    assert (tmp_path / "feed_rate_map.png").stat().st_size > 10_000


def test_the_console_script_reports_its_version():
    out = subprocess.run(
        [sys.executable, "-m", "upm.cli", "--version"], capture_output=True, text=True, check=True
    )
    assert out.stdout.startswith("upm ")


@pytest.mark.parametrize("script", sorted((ROOT / "examples").glob("*.py")), ids=lambda p: p.name)
def test_example_runs(script, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    runpy.run_path(str(script), run_name="__main__")
    assert capsys.readouterr().out.strip()
