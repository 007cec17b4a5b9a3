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


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["figures", "--out", "/proc/nope"], "upm: cannot use '/proc/nope'"),
        (["demo", "--out", "/proc/x"], "upm: cannot use"),
        (["demo", "nosuchdemo"], "the demos: feeding, list, bowtie"),
        (["emulate", "--tcp", "-5"], "--tcp: must be a TCP port in [0, 65535]; got -5"),
        (["emulate", "--drop", "2"], "--drop: must be a probability in [0, 1]; got 2"),
        (["emulate", "--scene", "/nonexistent.json"], "--scene /nonexistent.json"),
    ],
)
def test_cli_errors_are_one_line_not_a_traceback(argv, message):
    # Before: tracebacks (--out /proc/x, --tcp -5), a wrong demo list, --drop 2 accepted.
    out = subprocess.run(
        [sys.executable, "-m", "upm.cli", *argv], capture_output=True, text=True, timeout=120
    )
    assert out.returncode == 2, out.stderr
    assert message in out.stderr and "Traceback" not in out.stderr


def test_every_emulator_option_has_help():
    out = subprocess.run(
        [sys.executable, "-m", "upm.cli", "emulate", "--help"], capture_output=True, text=True, check=True
    )
    for option in ("--seed", "--watchdog-ms", "--duplicate", "--corrupt", "--snr-db", "--scene"):
        line = out.stdout.split(option, 1)[1].split("\n  -", 1)[0]
        assert len(line.split()) > 2, f"{option} has no help: {line!r}"


@pytest.mark.parametrize(
    ("blocked", "code", "extra"),
    [
        ("cobs", "from upm import control", "upm[board]"),
        ("xarray", "import upm; upm.sweep('jet_focus', {'rho': [0.1]})", "upm[sweep]"),
        ("cv2", "import upm.vision", "upm[vision]"),
        ("matplotlib", "from upm import plot; plot.feeding_versus_b()", "upm[plot]"),
        ("cobs", "from upm import cli; cli.main(['emulate', '--help'])", "upm[board]"),
    ],
)
def test_a_missing_extra_names_what_to_install(blocked, code, extra):
    script = f"import sys; sys.modules[{blocked!r}] = None\n{code}"
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
    assert f"pip install '{extra}'" in out.stderr, out.stderr
    assert "ModuleNotFoundError" not in out.stderr
