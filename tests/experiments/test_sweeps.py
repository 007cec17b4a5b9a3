"""Parameter sweeps: labelled results, known answers of the built-in scenarios, identical results
for any thread count and on Dask, resuming after a crash, bad grids failing before any work."""

from __future__ import annotations

import threading
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
import zarr

import upm
from upm import cli, plot
from upm.experiments.sweeps import SCENARIOS


class Counter:
    """A target that counts its calls (and can crash once after ``crash_after`` calls)."""

    def __init__(self, crash_after: int | None = None) -> None:
        self.calls: list[tuple[float, float]] = []
        self.crash_after = crash_after
        self.lock = threading.Lock()

    def __call__(self, x: float, y: float, scale: float = 1.0) -> dict[str, object]:
        with self.lock:
            if self.crash_after is not None and len(self.calls) >= self.crash_after:
                self.crash_after = None
                raise RuntimeError("simulated crash")
            self.calls.append((x, y))
        return {"sum": scale * (x + y), "pair": np.array([x, y * y])}


# -- built-in scenarios against independent references -----------------------------------


def test_feed_rate_scenario_tends_to_the_quasi_static_limit() -> None:
    ds = upm.sweep("feed_rate", {"b": [0.5, 1.0], "gamma": [0.8, 60.0]}, phi=np.pi / 2, progress=False)
    assert ds.feed_rate.dims == ("b", "gamma") and ds.feed_rate.shape == (2, 2)
    np.testing.assert_allclose(ds.b, [0.5, 1.0])
    # SPEC §2.2 known answers for the quasi-static limit (3.17) and the force at rest
    np.testing.assert_allclose(ds.feed_rate_qs.sel(gamma=60.0), [0.5, 0.25], atol=1e-6)
    np.testing.assert_allclose(ds.force_at_rest.sel(gamma=60.0), [0.2386, 0.3333], atol=1e-4)
    # the plate never out-accelerates friction (gamma < 1): the part rides along, no feed at all
    assert np.abs(ds.feed_rate.sel(gamma=0.8)).max() < 1e-12
    # far above, the exact integrator reaches the median of v (within 2%)
    np.testing.assert_allclose(ds.feed_rate.sel(gamma=60.0), [0.5, 0.25], rtol=0.02)
    # amplitude sized so that the peak acceleration is gamma mu g
    t = np.linspace(0, 2 * np.pi, 20001)
    peak = np.abs(np.cos(t) + 2 * 0.5 * np.cos(2 * t + np.pi / 2)).max()
    w = 2 * np.pi * 35.0
    assert float(ds.amplitude.sel(b=0.5, gamma=60.0)) * w * peak == pytest.approx(60 * 0.3 * 9.81, rel=1e-4)


def test_jet_focus_scenario_scales_with_rho() -> None:
    ds = upm.sweep("jet_focus", {"rho": [0.01, 0.02, 0.05]}, progress=False)
    np.testing.assert_allclose(ds.force_at_center, 1 / 3, atol=1e-6)  # the jet's focus (SPEC §7)
    ratio = ds.half_force_radius_over_rho.values
    assert 0.1 < ratio[0] < 2 and np.ptp(ratio) < 1e-6  # the field is scale-free in rho


def test_rotation_accuracy_scenario() -> None:
    ds = upm.sweep(
        "rotation_accuracy", {"spacing": [0.02, 0.1], "n_centers": [8, 16]}, trials=3, progress=False
    )
    assert ds.residual.max() < 1e-9  # 2M rows, N >= 2M centres: exactly solvable
    assert np.all(ds.flow_error.sel(spacing=0.02) > ds.flow_error.sel(spacing=0.1))  # crowding costs
    assert np.all(ds.condition >= 1)
    with pytest.raises(upm.ParameterError, match="n_centers >= 2 parts"):
        upm.sweep("rotation_accuracy", {"spacing": [0.05], "n_centers": [6]}, progress=False)


@pytest.mark.slow
def test_mchip_feed_scenario_runs_the_array_per_point() -> None:
    # Two duty cycles, 15 ms each, on two threads: each point is one rapier3d run of upm.mchip, the
    # same as calling it directly.
    ds = upm.sweep("mchip_feed", {"duty": [0.36, 0.5]}, duration=0.015, n_jobs=2, progress=False)
    assert ds.feed_rate.dims == ("duty",) and np.all(ds.feed_rate > 0)
    assert np.all((ds.rebound_share >= 0) & (ds.rebound_share <= 1)) and np.all(ds.collisions > 0)
    direct = upm.mchip.simulate(drive=upm.mchip.Drive(duty=0.5), duration=0.015, record_every=20)
    assert float(ds.feed_rate.sel(duty=0.5)) == direct.feed_rate(skip=0.3 * 0.015)
    # Fig. 2.9's other curves: the impacts catch the ridge on its way up, within its stroke, and
    # the part rides on the ridges (5 µm high), hopping tens of µm in its first 15 ms.
    assert np.all((ds.impact_angle > 0) & (ds.impact_angle < 0.1)) and np.all(ds.impact_angular_speed > 0)
    assert np.all((ds.part_height > 5e-6) & (ds.part_height < 50e-6))
    assert float(ds.part_height.sel(duty=0.5)) == direct.part_height(skip=0.3 * 0.015)
    jammed = sum(b - a for a, b in direct.jams(skip=0.3 * 0.015)) / (direct.t[-1] - 0.3 * 0.015)
    assert float(ds.jam_share.sel(duty=0.5)) == jammed and np.all((ds.jam_share >= 0) & (ds.jam_share <= 1))
    # The joint's natural frequency and quality factor reach the simulation.
    soft = upm.sweep("mchip_feed", {"natural_frequency": [1500.0], "quality": [2.0]}, duration=0.015,
                     progress=False)  # fmt: skip
    alone = upm.mchip.simulate(upm.mchip.Design(natural_frequency=1500.0, quality=2.0), duration=0.015,
                               record_every=20)  # fmt: skip
    assert float(soft.feed_rate[0, 0]) == alone.feed_rate(skip=0.3 * 0.015)
    assert float(soft.feed_rate[0, 0]) != float(ds.feed_rate.sel(duty=0.5))
    # A run too short for one 10 ms window after its first 3 ms has no jam share.
    brief = upm.sweep("mchip_feed", {"duty": [0.5]}, duration=0.01, progress=False)
    assert np.isnan(float(brief.jam_share[0])) and float(brief.feed_rate[0]) > 0
    # Replicas: another seed starts the part elsewhere and the run comes out otherwise; the same
    # seed, the same run.
    reps = upm.sweep("mchip_feed", {"seed": [0, 7, 7]}, duration=0.015, n_jobs=2, progress=False)
    assert float(reps.feed_rate[0]) == float(ds.feed_rate.sel(duty=0.5))
    assert float(reps.feed_rate[1]) == float(reps.feed_rate[2]) != float(reps.feed_rate[0])
    with pytest.raises(upm.ParameterError, match="ridge_distance"):
        upm.sweep("mchip_feed", {"ridge_distance": [1e-3]}, progress=False)
    with pytest.raises(upm.ParameterError, match="seed"):
        upm.sweep("mchip_feed", {"seed": [0.5]}, progress=False)


# -- functions, shapes, labels -------------------------------------------------------------


def test_function_target_with_array_outputs() -> None:
    target = Counter()
    ds = upm.sweep(target, {"x": [0.0, 1.0, 2.0], "y": [10.0, 20.0]}, scale=2.0, chunk=2, progress=False)
    assert ds["sum"].dims == ("x", "y")
    np.testing.assert_allclose(ds["sum"], 2.0 * (np.array([0, 1, 2])[:, None] + np.array([10, 20])))
    assert ds["pair"].dims == ("x", "y", "pair_0") and ds["pair"].shape == (3, 2, 2)
    np.testing.assert_allclose(ds["pair"].sel(x=2.0, y=20.0), [2.0, 400.0])
    assert sorted(target.calls) == sorted((x, y) for x in (0.0, 1.0, 2.0) for y in (10.0, 20.0))

    ds = upm.sweep(lambda n: n * n, {"n": [1, 2, 3]}, progress=False)
    assert list(ds.data_vars) == ["result"] and ds.result.values.tolist() == [1, 4, 9]


def test_same_results_for_one_and_two_threads() -> None:
    grid = {"b": [0.3, 0.5, 0.8], "gamma": [3.0, 10.0]}
    one = upm.sweep("feed_rate", grid, phi=1.2, periods=12, n_jobs=1, chunk=1, progress=False)
    two = upm.sweep("feed_rate", grid, phi=1.2, periods=12, n_jobs=2, chunk=1, progress=False)
    xr.testing.assert_identical(one, two)


def test_dask_backend_matches_threads() -> None:
    distributed = pytest.importorskip("distributed")
    grid = {"b": [0.3, 0.5], "gamma": [3.0, 10.0]}
    local = upm.sweep("feed_rate", grid, phi=1.2, periods=12, chunk=1, progress=False)
    with (
        distributed.LocalCluster(
            n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
        ) as cluster,
        distributed.Client(cluster) as client,
    ):
        remote = upm.sweep("feed_rate", grid, phi=1.2, periods=12, chunk=1, backend="dask", client=client,
                           progress=False)  # fmt: skip
        # functions travel by value (cloudpickle), with plain parameters
        functions = upm.sweep(lambda x, y: {"sum": x + y}, {"x": [1.0, 2.0], "y": [3.0]}, backend="dask",
                              client=client, progress=False)  # fmt: skip
    xr.testing.assert_identical(local, remote)
    np.testing.assert_allclose(functions["sum"], [[4.0], [5.0]])


# -- storage and resuming ------------------------------------------------------------------


def test_a_crashed_sweep_resumes_without_recomputing(tmp_path: Path) -> None:
    grid = {"x": np.arange(6.0), "y": np.arange(4.0)}  # chunks of 4 points: one row of y each
    store = tmp_path / "run.zarr"
    crashing = Counter(crash_after=10)
    with pytest.raises(RuntimeError, match="simulated crash"):
        upm.sweep(crashing, grid, store=store, chunk=4, n_jobs=1, progress=False)
    done = np.asarray(zarr.open_group(str(store), mode="r")["_done"][...])
    assert done.sum() == 2  # chunks 0 and 1 finished and stored; chunk 2 crashed halfway
    resumed = Counter()
    ds = upm.sweep(resumed, grid, store=store, chunk=4, n_jobs=1, progress=False)
    assert len(resumed.calls) == 24 - 8 and all(x >= 2 for x, _ in resumed.calls)  # nothing stored redone
    fresh = upm.sweep(Counter(), grid, chunk=4, progress=False)
    xr.testing.assert_allclose(ds[["sum", "pair"]], fresh[["sum", "pair"]])
    # finished: a third run computes nothing and reads the store
    idle = Counter()
    again = upm.sweep(idle, grid, store=store, chunk=4, progress=False)
    assert idle.calls == [] and again["sum"].equals(ds["sum"])
    # the store is an ordinary labelled Zarr dataset
    assert float(xr.open_zarr(store, consolidated=False)["sum"].sel(x=5.0, y=3.0)) == 8.0


def test_a_store_of_another_sweep_is_refused_unless_overwritten(tmp_path: Path) -> None:
    store = tmp_path / "run.zarr"
    upm.sweep(Counter(), {"x": [1.0, 2.0], "y": [0.0]}, store=store, progress=False)
    target = Counter()
    with pytest.raises(upm.ParameterError, match="different sweep"):
        upm.sweep(target, {"x": [1.0, 3.0], "y": [0.0]}, store=store, progress=False)
    assert target.calls == []
    ds = upm.sweep(target, {"x": [1.0, 3.0], "y": [0.0]}, store=store, resume=False, progress=False)
    np.testing.assert_allclose(ds["sum"], [[1.0], [3.0]])


# -- bad grids fail before any work --------------------------------------------------------


@pytest.mark.parametrize(
    ("grid", "fixed", "message"),
    [
        ({"x": [], "y": [1.0]}, {}, "empty"),
        ({"x": [1.0, np.nan], "y": [1.0]}, {}, "finite"),
        ({"x": [1.0], "z": [1.0]}, {}, "unknown parameter 'z'"),
        ({"x": [[1.0, 2.0]], "y": [1.0]}, {}, "1-D"),
        ({"x": [1.0]}, {}, r"\['y'\]"),
        ({}, {}, "non-empty"),
    ],
)
def test_bad_grids_for_functions(grid: dict, fixed: dict, message: str) -> None:
    target = Counter()
    with pytest.raises(upm.ParameterError, match=message):
        upm.sweep(target, grid, progress=False, **fixed)
    assert target.calls == []


@pytest.mark.parametrize(
    ("grid", "fixed", "message"),
    [
        (
            {"b": [0.5], "gamma": [1.0], "nonsense": [1.0]},
            {},
            "unknown parameter 'nonsense'.*allowed: b, phi",
        ),
        ({"b": [0.5], "gamma": [-1.0]}, {"phi": 1.0}, r"gamma.*\[0, 1000\]"),
        ({"b": [0.5], "gamma": [2.0]}, {}, r"needs \['phi'\]"),
        ({"b": [0.5], "gamma": [2.0]}, {"phi": 1.0, "periods": 2.5}, "integers"),
        ({"b": [0.5], "gamma": [2.0]}, {"phi": 1.0, "periods": 5}, "must exceed"),
        ({"rho": [np.inf]}, {}, "finite"),
    ],
)
def test_bad_grids_for_scenarios(grid: dict, fixed: dict, message: str) -> None:
    target = "jet_focus" if "rho" in grid else "feed_rate"
    with pytest.raises(upm.ParameterError, match=message):
        upm.sweep(target, grid, progress=False, **fixed)


def test_bad_options() -> None:
    with pytest.raises(upm.ParameterError, match="unknown scenario 'feed'"):
        upm.sweep("feed", {"b": [1.0]})
    with pytest.raises(upm.ParameterError, match="backend"):
        upm.sweep(Counter(), {"x": [1.0], "y": [1.0]}, backend="mpi")
    with pytest.raises(upm.ParameterError, match="client"):
        upm.sweep(Counter(), {"x": [1.0], "y": [1.0]}, backend="dask")
    with pytest.raises(upm.ParameterError, match="n_jobs"):
        upm.sweep(Counter(), {"x": [1.0], "y": [1.0]}, n_jobs=0)


# -- progress, plots, command line ---------------------------------------------------------


def test_progress_bar_and_quiet_mode(capsys: pytest.CaptureFixture[str]) -> None:
    upm.sweep(Counter(), {"x": [1.0, 2.0], "y": [1.0]}, progress=True)
    assert "sweep" in capsys.readouterr().err
    upm.sweep(Counter(), {"x": [1.0, 2.0], "y": [1.0]}, progress=False)
    assert capsys.readouterr().err == ""


def test_plot_sweep_heat_map_and_line() -> None:
    ds = upm.sweep(Counter(), {"x": [0.0, 1.0, 2.0], "y": [1.0, 2.0]}, progress=False)
    fig = plot.sweep(ds, "sum")
    assert fig.axes[0].get_xlabel() == "y" and fig.axes[0].get_ylabel() == "x"
    fig = plot.sweep(ds, "sum", x="x", y="y")
    assert fig.axes[0].get_xlabel() == "x"
    line = plot.sweep(ds["sum"].isel(y=0))
    assert line.axes[0].get_xlabel() == "x"
    with pytest.raises(upm.ParameterError, match="not a dimension"):
        plot.sweep(ds, "sum", x="q")


def test_cli_sweep_list_and_config(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys) -> None:
    assert cli.main(["sweep", "--list"]) == 0
    listed = capsys.readouterr().out
    assert all(name in listed for name in SCENARIOS)
    monkeypatch.chdir(tmp_path)
    (tmp_path / "jet.toml").write_text(
        'target = "jet_focus"\nplot = "out/jet.png"\n'
        "[grid]\nrho = {start = 0.01, stop = 0.04, num = 3, log = true}\n"
    )
    assert cli.main(["sweep", "jet.toml", "--quiet"]) == 0
    assert (tmp_path / "out" / "jet_focus.zarr").exists() and (tmp_path / "out" / "jet.png").exists()
    np.testing.assert_allclose(
        xr.open_zarr(tmp_path / "out" / "jet_focus.zarr", consolidated=False).rho, [0.01, 0.02, 0.04]
    )
    (tmp_path / "bad.toml").write_text('target = "jet_focus"\n[grid]\nrho = []\n')
    assert cli.main(["sweep", "bad.toml", "--quiet"]) == 2
    assert "empty" in capsys.readouterr().err


def test_a_store_knows_which_function_filled_it(tmp_path: Path) -> None:
    # Before: a store identified a function by name only, so another lambda got the first one's
    # results silently.
    store = tmp_path / "f.zarr"
    grid = {"x": [1.0, 2.0]}
    first = upm.sweep(lambda x: {"y": x}, grid, store=store, progress=False)
    with pytest.raises(upm.ParameterError, match="different sweep"):
        upm.sweep(lambda x: {"y": 10 * x}, grid, store=store, progress=False)
    scale = 3.0
    with pytest.raises(upm.ParameterError, match="different sweep"):  # same body, other closure
        upm.sweep(lambda x: {"y": scale * x}, grid, store=store, progress=False)
    again = upm.sweep(lambda x: {"y": x}, grid, store=store, progress=False)  # the same code: resumes
    xr.testing.assert_equal(first, again)


def test_a_stored_sweep_keeps_its_variable_order_and_units(tmp_path: Path) -> None:
    # Before: read back as ['force_at_rest', 'amplitude', 'feed_rate_qs', 'feed_rate'].
    grid = {"b": [0.25, 0.5], "gamma": [0.8, 5.0]}
    fresh = upm.sweep("feed_rate", grid, phi=np.pi / 2, steps=64, progress=False)
    stored = upm.sweep("feed_rate", grid, phi=np.pi / 2, steps=64, store=tmp_path / "s.zarr", progress=False)
    order = list(SCENARIOS["feed_rate"].outputs)
    assert list(fresh.data_vars) == order and list(stored.data_vars) == order
    assert stored["amplitude"].attrs["units"] == "m/s" and stored["feed_rate"].attrs["units"] == "1"


def test_log_spaced_axes_are_drawn_on_a_log_scale() -> None:
    ds = upm.sweep(lambda x, y: {"z": x * y}, {"x": np.geomspace(1e-3, 1.0, 7), "y": [1.0, 2.0, 3.0]},
                   progress=False)  # fmt: skip
    fig = plot.sweep(ds, x="x", y="y")
    ax = fig.axes[0]
    assert ax.get_xscale() == "log" and ax.get_yscale() == "linear"
    line = plot.sweep(ds.isel(y=0).drop_vars("y"))
    assert line.axes[0].get_xscale() == "log"
