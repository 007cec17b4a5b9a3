"""Parameter sweeps: labelled, resumable, parallel, ready for a cluster.

:func:`sweep` evaluates a target (a built-in scenario, or any function of keyword parameters) on
every point of a grid and returns an :class:`xarray.Dataset` with one dimension per grid axis.
The grid is cut into hyper-rectangular chunks (``chunk`` points each, whole trailing axes first);
chunks run on a pool of threads (the built-in scenarios call the Rust core on one thread per
chunk, GIL released) or on a Dask cluster, and each finished chunk is written to a Zarr store
(``store=``) together with a mark that it is done, so that a crashed or interrupted sweep
restarted with ``resume=True`` computes only what is missing. Results do not depend on the
backend or the number of threads: every chunk is computed independently.

Needs the ``sweep`` extra: ``pip install 'upm[sweep]'`` (xarray, zarr, dask[distributed], tqdm).
"""

from __future__ import annotations

import concurrent.futures as cf
import hashlib
import inspect
import json
import math
import os
import shutil
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .._arrays import as_float, as_int
from .._errors import ParameterError
from .._extras import need
from .scenarios import SCENARIOS, Outputs, Scenario

__all__ = ["SCENARIOS", "Scenario", "sweep"]


# -- the grid and its chunks ----------------------------------------------------------------


@dataclass(frozen=True)
class _Plan:
    name: str
    axes: dict[str, NDArray[Any]]
    fixed: dict[str, Any]
    chunk_shape: tuple[int, ...]

    @property
    def shape(self) -> tuple[int, ...]:
        return tuple(len(v) for v in self.axes.values())

    @property
    def grid_chunks(self) -> tuple[int, ...]:
        return tuple(math.ceil(n / c) for n, c in zip(self.shape, self.chunk_shape, strict=True))

    def chunks(self) -> Iterator[tuple[int, tuple[slice, ...]]]:
        for flat, index in enumerate(np.ndindex(*self.grid_chunks)):
            yield (
                flat,
                tuple(
                    slice(i * c, min((i + 1) * c, n))
                    for i, c, n in zip(index, self.chunk_shape, self.shape, strict=True)
                ),
            )

    def points(self, region: tuple[slice, ...]) -> dict[str, NDArray[Any]]:
        values = [v[s] for v, s in zip(self.axes.values(), region, strict=True)]
        mesh = np.meshgrid(*values, indexing="ij")
        return {k: m.ravel() for k, m in zip(self.axes, mesh, strict=True)}

    def attrs(self) -> dict[str, str]:
        """The dataset's attributes: the target's name and the fixed parameters."""
        return {"target": self.name, "fixed": json.dumps({k: repr(v) for k, v in self.fixed.items()})}

    def fingerprint(self) -> str:
        spec = {
            "target": self.name,
            "axes": {k: np.asarray(v).tolist() for k, v in self.axes.items()},
            "fixed": {k: repr(v) for k, v in sorted(self.fixed.items())},
            "chunk": list(self.chunk_shape),
        }
        return hashlib.sha256(json.dumps(spec, sort_keys=True).encode()).hexdigest()


def _code_identity(target: Callable[..., Any]) -> str:
    """A short hash of what a function target computes: its bytecode, constants, names, defaults
    and closure values (not its file or line, so moving it does not invalidate a store; for a
    callable instance, its class's ``__call__``). Two
    lambdas with the same name but different bodies differ; so do equal bodies closing over
    different values."""
    fn: Any = getattr(target, "__func__", target)
    code = getattr(fn, "__code__", None)
    if code is None:  # a callable instance: its class's __call__ (its state is its own business)
        owner = next((k for k in type(target).__mro__ if "__call__" in vars(k)), None)
        code = getattr(vars(owner).get("__call__"), "__code__", None) if owner is not None else None
        extra = ""
    else:
        cells = [c.cell_contents for c in (fn.__closure__ or ()) if _has_contents(c)]
        extra = repr((fn.__defaults__, fn.__kwdefaults__, cells))
    digest = hashlib.sha256()

    def feed(c: Any) -> None:
        digest.update(c.co_code)
        digest.update(repr(c.co_names).encode())
        for const in c.co_consts:
            if hasattr(const, "co_code"):
                feed(const)  # nested functions and comprehensions
            else:
                digest.update(repr(const).encode())

    if code is not None:
        feed(code)
    digest.update(extra.encode())
    return digest.hexdigest()[:16]


def _has_contents(cell: Any) -> bool:
    try:
        _ = cell.cell_contents
    except ValueError:  # an empty cell
        return False
    return True


def _units(description: str) -> str:
    """The unit in a description's trailing ``[...]``; ``"1"`` (dimensionless) without one."""
    if description.rstrip().endswith("]") and "[" in description:
        return description.rstrip()[description.rindex("[") + 1 : -1]
    return "1"


def _chunk_shape(shape: tuple[int, ...], points: int) -> tuple[int, ...]:
    """Whole trailing axes first, until a chunk holds about ``points`` points."""
    out = []
    room = max(points, 1)
    for n in reversed(shape):
        c = max(1, min(n, room))
        out.append(c)
        room = max(1, room // c)
    return tuple(reversed(out))


def _check_axis(name: str, values: Any, allowed: tuple[float, float] | None, integer: bool) -> NDArray[Any]:
    a = np.asarray(values)
    if a.ndim == 0:
        a = a.reshape(1)
    if a.ndim != 1:
        raise ParameterError(f"grid axis {name!r} must be a 1-D sequence of values; got shape {a.shape}")
    if a.size == 0:
        raise ParameterError(f"grid axis {name!r} is empty; give it at least one value")
    if a.dtype.kind in "US":
        return a
    v = as_float(f"grid axis {name!r}", a)
    if allowed is not None:
        lo, hi = allowed
        bad = np.nonzero((v < lo) | (v > hi))[0]
        if len(bad):
            raise ParameterError(
                f"grid axis {name!r} must lie in [{lo:g}, {hi:g}]; got {v[bad[0]]} at index {bad[0]}"
            )
    if integer:
        if np.any(v != np.round(v)):
            raise ParameterError(f"grid axis {name!r} must hold integers; got {v.tolist()}")
        return v.astype(np.int64)
    return v if a.dtype.kind == "f" else a


def _plan(target: str | Callable[..., Any], grid: Mapping[str, Any], fixed: dict[str, Any],
          chunk: int | None) -> tuple[_Plan, Scenario | None]:  # fmt: skip
    if not isinstance(grid, Mapping) or not grid:
        raise ParameterError("grid must be a non-empty mapping of parameter name -> values")
    both = sorted(set(grid) & set(fixed))
    if both:
        raise ParameterError(
            f"{both} given both as grid axes and as fixed parameters: the fixed value would be dropped; "
            "give each parameter once"
        )
    scenario = None
    if isinstance(target, str):
        if target not in SCENARIOS:
            raise ParameterError(f"unknown scenario {target!r}; built in: {', '.join(SCENARIOS)}")
        scenario = SCENARIOS[target]
        allowed = scenario.parameters
        for name in [*grid, *fixed]:
            if name not in allowed:
                raise ParameterError(
                    f"unknown parameter {name!r} for scenario {target!r}; allowed: {', '.join(allowed)}"
                )
        axes = {k: _check_axis(k, v, scenario.ranges[k], k in scenario.integers) for k, v in grid.items()}
        for k, v in fixed.items():
            _check_axis(k, [v], scenario.ranges[k], k in scenario.integers)
        missing = [k for k in scenario.required if k not in grid and k not in fixed]
        if missing:
            raise ParameterError(f"scenario {target!r} needs {missing} as grid axes or fixed parameters")
        if scenario.check is not None:
            merged = {**scenario.defaults, **fixed}
            scenario.check(lambda k: np.asarray(axes[k]) if k in axes else np.asarray([merged[k]]))
        name = target
        default_chunk = scenario.chunk
    elif callable(target):
        sig = inspect.signature(target)
        kinds = {p.kind for p in sig.parameters.values()}
        takes_any = inspect.Parameter.VAR_KEYWORD in kinds
        for k in [*grid, *fixed]:
            if not takes_any and k not in sig.parameters:
                raise ParameterError(
                    f"unknown parameter {k!r}: {getattr(target, '__name__', 'target')} takes "
                    f"{', '.join(sig.parameters) or 'no parameters'}"
                )
        missing = [
            p.name
            for p in sig.parameters.values()
            if p.default is inspect.Parameter.empty
            and p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)
            and p.name not in grid
            and p.name not in fixed
        ]
        if missing:
            raise ParameterError(f"parameters {missing} of the target are neither grid axes nor fixed")
        axes = {k: _check_axis(k, v, None, False) for k, v in grid.items()}
        # the function's name identifies the sweep in a store (an instance: its class's name)
        named = target if hasattr(target, "__qualname__") else type(target)
        name = f"{named.__module__}.{named.__qualname__}#{_code_identity(target)}"
        default_chunk = 16
    else:
        raise ParameterError(f"target must be a scenario name or a function; got {target!r}")
    points = default_chunk if chunk is None else as_int("chunk", chunk)
    if points < 1:
        raise ParameterError(f"chunk must be >= 1 points; got {points}")
    shape = tuple(len(v) for v in axes.values())
    return _Plan(name, axes, dict(fixed), _chunk_shape(shape, points)), scenario


# -- running one chunk (also on Dask workers: plain arguments only) ---------------------------


def run_chunk(
    target: str | Callable[..., Any], points: dict[str, NDArray[Any]], fixed: dict[str, Any]
) -> Outputs:
    """Evaluate ``target`` on the points of one chunk: ``{output: (n, ...) array}``."""
    n = len(next(iter(points.values())))
    if isinstance(target, str):
        scenario = SCENARIOS[target]
        params = {k: np.full(n, v) for k, v in {**scenario.defaults, **fixed}.items()}
        params.update({k: np.asarray(v) for k, v in points.items()})
        return {k: np.asarray(v) for k, v in scenario.run(params).items()}
    rows: list[dict[str, Any]] = []
    for i in range(n):
        value = target(**{k: _scalar(v[i]) for k, v in points.items()}, **fixed)
        rows.append(dict(value) if isinstance(value, Mapping) else {"result": value})
    names = list(rows[0])
    for i, row in enumerate(rows):
        if list(row) != names:
            raise ParameterError(
                f"the target returned outputs {list(row)} at point {i} but {names} at point 0"
            )
    return {k: np.stack([np.asarray(r[k]) for r in rows]) for k in names}


def _scalar(v: Any) -> Any:
    return v.item() if isinstance(v, np.generic) else v


# -- storage ----------------------------------------------------------------------------------


class _Store:
    """A Zarr store holding the sweep's variables and one ``_done`` flag per chunk."""

    def __init__(self, path: Path, plan: _Plan, resume: bool) -> None:
        zarr = need("zarr", "sweep", "a sweep store")

        self.path, self.plan = path, plan
        self.done = np.zeros(plan.grid_chunks, bool)
        self.group: Any = None
        if path.exists() and resume:
            try:
                group = zarr.open_group(str(path), mode="r+")
                found = group.attrs.get("upm_sweep")
            except Exception as error:
                raise ParameterError(
                    f"store {str(path)!r} exists but is not a readable Zarr store: {error}"
                ) from error
            if found != plan.fingerprint():
                raise ParameterError(
                    f"store {str(path)!r} holds a different sweep (target, grid, fixed parameters or chunks "
                    "differ); pass resume=False to overwrite it, or another store"
                )
            self.group = group
            flags: Any = group["_done"]
            self.done = np.asarray(flags[...], dtype=bool)
        elif path.exists():
            shutil.rmtree(path)

    def create(self, first: Outputs) -> None:
        """Lay out the store from the first chunk's output blocks (their dtypes and the shapes
        after the grid's axes)."""
        if self.group is not None:
            return
        xr = need("xarray", "sweep", "upm.sweep")

        da: Any = need("dask.array", "sweep", "a sweep with backend='dask'", "dask")

        plan = self.plan
        dims = list(plan.axes)
        data = {}
        for k, v in first.items():
            extra = v.shape[len(dims) :]
            chunks = (*plan.chunk_shape, *extra)
            fill = np.nan if v.dtype.kind in "fc" else 0
            data[k] = (dims + [f"{k}_{j}" for j in range(len(extra))], da.full((*plan.shape, *extra), fill,
                       dtype=v.dtype, chunks=chunks))  # fmt: skip
        data["_done"] = ([f"_chunk_{d}" for d in dims], da.zeros(plan.grid_chunks, dtype=bool, chunks=1))
        ds = xr.Dataset(data, coords=dict(plan.axes), attrs=plan.attrs())
        ds.attrs["upm_sweep"] = plan.fingerprint()
        ds.attrs["upm_variables"] = json.dumps(list(first))  # the target's order, kept on reading
        ds.to_zarr(str(self.path), mode="w", compute=False, consolidated=False)
        zarr = need("zarr", "sweep", "a sweep store")

        self.group = zarr.open_group(str(self.path), mode="r+")

    def write(self, index: tuple[int, ...], region: tuple[slice, ...], block: Outputs) -> None:
        if not hasattr(self, "_arrays"):  # opened once: every lookup reads metadata from disk
            self._arrays = {k: self.group[k] for k in [*block, "_done"]}
        for k, v in block.items():
            self._arrays[k][region] = v
        self._arrays["_done"][index] = True  # after the data: a chunk cut short is computed again
        self.done[index] = True


# -- the sweep --------------------------------------------------------------------------------


class _NoBar:
    """What a sweep without ``progress`` uses in place of tqdm's bar (tqdm need not be installed)."""

    def __init__(self, **_: Any) -> None:
        pass

    def update(self, _: int) -> None:
        pass

    def close(self) -> None:
        pass


def sweep(
    target: str | Callable[..., Any],
    grid: Mapping[str, Any],
    *,
    n_jobs: int | None = None,
    backend: str = "threads",
    client: Any = None,
    store: str | os.PathLike[str] | None = None,
    resume: bool = True,
    progress: bool = True,
    chunk: int | None = None,
    **fixed: Any,
) -> Any:
    """Evaluate ``target`` over every point of ``grid``; an :class:`xarray.Dataset`.

    Parameters
    ----------
    target : str or callable
        A built-in scenario (``"feed_rate"``, ``"jet_focus"``, ``"rotation_accuracy"``; see
        :data:`SCENARIOS`, ``upm sweep --list``) or a function of keyword parameters returning
        a scalar, an array, or a mapping of output names to scalars/arrays.
    grid : mapping of str to 1-D sequence
        One axis per parameter, in the order of the result's dimensions.
    n_jobs : int, optional
        Threads running chunks (default: one per core). Ignored by ``backend="dask"``.
    backend : {"threads", "dask"}
        Where chunks run: a local thread pool, or the Dask cluster of ``client``.
    client : dask.distributed.Client or str, optional
        The client (or scheduler address) for ``backend="dask"``. Workers receive the scenario
        name or the (pickled) function and plain NumPy parameters.
    store : path, optional
        A Zarr store (a directory, e.g. ``"feed.zarr"``) written chunk by chunk as they finish.
    resume : bool
        Reuse a store of the same sweep: chunks marked done are not computed again. ``False``
        overwrites the store.
    progress : bool
        Show a progress bar with ETA (tqdm, on stderr).
    chunk : int, optional
        Points per chunk (default: the scenario's, 16 for functions).
    **fixed
        Parameters held fixed (for scenarios: overriding their defaults).

    Returns
    -------
    xarray.Dataset
        One variable per output, dimensions = the grid's axes (plus ``<output>_<k>`` for array
        outputs), coordinates = the grid's values; ``attrs["target"]`` and ``attrs["fixed"]``.

    Raises
    ------
    ParameterError
        Before any work: an empty axis, an unknown parameter, a non-finite or out-of-range value,
        a store holding another sweep.
    """
    xr = need("xarray", "sweep", "upm.sweep")
    tqdm = need("tqdm.auto", "sweep", "upm.sweep", "tqdm").tqdm if progress else _NoBar

    plan, scenario = _plan(target, grid, fixed, chunk)
    if backend not in ("threads", "dask"):
        raise ParameterError(f"backend must be 'threads' or 'dask'; got {backend!r}")
    workers = (os.cpu_count() or 1) if n_jobs is None else as_int("n_jobs", n_jobs)
    if workers < 1:
        raise ParameterError(f"n_jobs must be >= 1; got {n_jobs}")
    if backend == "dask" and client is None:
        raise ParameterError(
            "backend='dask' needs client= (a dask.distributed.Client or a scheduler address)"
        )
    sink = _Store(Path(store), plan, resume) if store is not None else None
    results: Outputs = {}
    done = sink.done.copy() if sink is not None else np.zeros(plan.grid_chunks, bool)
    pending = [(i, r) for i, r in plan.chunks() if not done[np.unravel_index(i, plan.grid_chunks)]]
    total = int(np.prod(plan.shape))
    bar = tqdm(total=total, disable=not progress, unit="pt", desc=f"sweep {plan.name.rsplit('.', 1)[-1]}")
    bar.update(total - sum(int(np.prod([s.stop - s.start for s in r])) for _, r in pending))
    runner = target if scenario is None else scenario.name

    def finish(flat: int, region: tuple[slice, ...], out: Outputs) -> None:
        block_shape = tuple(s.stop - s.start for s in region)
        blocks = {k: v.reshape(*block_shape, *v.shape[1:]) for k, v in out.items()}
        if sink is not None:  # the result is read back from the store at the end (resumed chunks too)
            sink.create(blocks)
            sink.write(tuple(int(i) for i in np.unravel_index(flat, plan.grid_chunks)), region, blocks)
        else:
            for k, block in blocks.items():
                if k not in results:
                    fill = np.nan if block.dtype.kind in "fc" else 0
                    results[k] = np.full((*plan.shape, *block.shape[len(block_shape) :]), fill, block.dtype)
                results[k][region] = block
        bar.update(int(np.prod(block_shape)))

    try:
        if backend == "threads":
            with cf.ThreadPoolExecutor(max_workers=workers) as pool:
                futures = {
                    pool.submit(run_chunk, runner, plan.points(r), plan.fixed): (i, r) for i, r in pending
                }
                try:
                    for fut in cf.as_completed(futures):
                        finish(*futures[fut], fut.result())
                except BaseException:
                    pool.shutdown(wait=False, cancel_futures=True)
                    raise
        else:
            distributed: Any = need("distributed", "sweep", "a sweep on a dask client", "dask[distributed]")
            own = not isinstance(client, distributed.Client)  # an address: connect, and close after
            dask_client = distributed.Client(client) if own else client
            jobs: dict[Any, tuple[int, tuple[slice, ...]]] = {
                dask_client.submit(run_chunk, runner, plan.points(r), plan.fixed, pure=False): (i, r)
                for i, r in pending
            }
            try:
                for job in distributed.as_completed(list(jobs)):
                    finish(*jobs[job], job.result())
            except BaseException:
                for job in jobs:
                    job.cancel()
                raise
            finally:
                if own:
                    dask_client.close()
    finally:
        bar.close()

    if sink is not None:
        ds = xr.open_zarr(str(sink.path), consolidated=False).drop_vars("_done").load()
        order = json.loads(ds.attrs.pop("upm_variables", "[]"))
        ds = ds[[k for k in order if k in ds] + [k for k in ds.data_vars if k not in order]]
    else:
        dims = list(plan.axes)
        ds = xr.Dataset(
            {k: (dims + [f"{k}_{j}" for j in range(v.ndim - len(dims))], v) for k, v in results.items()},
            coords=dict(plan.axes),
            attrs=plan.attrs(),
        )
    if scenario is not None:
        for k, unit in scenario.outputs.items():
            if k in ds:
                ds[k].attrs["description"] = unit
                ds[k].attrs["units"] = _units(unit)
    return ds
