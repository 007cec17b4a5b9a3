//! `upm._core`: the thin pyo3 binding of `upm-core`.
//!
//! This crate only converts arrays, releases the GIL and maps errors; all physics lives in
//! `upm-core`. Inputs arrive from the Python layer already broadcast to equal 1-D lengths (or as
//! `(B, K)` coefficient tables), float64; outputs are new NumPy arrays.

mod actuation;
mod arrays;
mod centroid;
mod disk;
mod errors;
mod field;
mod friction;
mod mchip;
mod motion;
mod plan;
mod polygon;
mod ppod;
mod sim;
mod simd;
mod solve;
mod theory;
mod waveform;

use pyo3::prelude::*;

/// Large blocks on cache lines: results streamed to memory a line at a time (see
/// `upm_core::aligned`).
#[global_allocator]
static ALLOCATOR: upm_core::aligned::LineAligned = upm_core::aligned::LineAligned;

/// Raises a Rust panic inside the guarded helper: lets the tests prove panics never reach Python.
#[pyfunction]
fn _panic_for_test(py: Python<'_>) -> PyResult<()> {
    errors::detached(py, || -> Result<(), errors::Failure> {
        panic!("deliberate test panic")
    })
}

#[pymodule]
fn _core(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add_class::<waveform::WaveformBatch>()?;
    m.add_class::<motion::PlateMotion>()?;
    m.add_class::<sim::Run>()?;
    m.add_class::<mchip::MChipRun>()?;
    m.add_class::<solve::Plans>()?;
    m.add_class::<ppod::Field>()?;
    m.add_function(wrap_pyfunction!(sim::simulate, m)?)?;
    m.add_function(wrap_pyfunction!(simd::simd_info, m)?)?;
    m.add_function(wrap_pyfunction!(mchip::mchip_simulate, m)?)?;
    m.add_function(wrap_pyfunction!(centroid::coverage_centroids, m)?)?;
    m.add_function(wrap_pyfunction!(actuation::motors_for, m)?)?;
    m.add_function(wrap_pyfunction!(actuation::velocity_amplitudes, m)?)?;
    m.add_function(wrap_pyfunction!(actuation::center_of_rotation, m)?)?;
    m.add_function(wrap_pyfunction!(actuation::axis_response, m)?)?;
    m.add_function(wrap_pyfunction!(actuation::axis_steps, m)?)?;
    m.add_function(wrap_pyfunction!(actuation::harmonic_fit, m)?)?;
    m.add_function(wrap_pyfunction!(actuation::velocity_from_fit, m)?)?;
    m.add_function(wrap_pyfunction!(actuation::positive_force, m)?)?;
    m.add_function(wrap_pyfunction!(actuation::corner_excursions, m)?)?;
    m.add_function(wrap_pyfunction!(plan::apply_rays, m)?)?;
    m.add_function(wrap_pyfunction!(plan::edge_penalty, m)?)?;
    m.add_function(wrap_pyfunction!(plan::distance_sum, m)?)?;
    m.add_function(wrap_pyfunction!(plan::overlap_penalty, m)?)?;
    m.add_function(wrap_pyfunction!(actuation::cor_from_accelerometers, m)?)?;
    m.add_function(wrap_pyfunction!(solve::solve, m)?)?;
    m.add_function(wrap_pyfunction!(solve::solve_batch, m)?)?;
    m.add_function(wrap_pyfunction!(solve::priorities, m)?)?;
    m.add_function(wrap_pyfunction!(solve::flow_error, m)?)?;
    m.add_function(wrap_pyfunction!(field::rotation_field, m)?)?;
    m.add_function(wrap_pyfunction!(field::rotation_curl, m)?)?;
    m.add_function(wrap_pyfunction!(field::jet_field, m)?)?;
    m.add_function(wrap_pyfunction!(field::average_field, m)?)?;
    m.add_function(wrap_pyfunction!(ppod::drift_field, m)?)?;
    m.add_function(wrap_pyfunction!(polygon::polygon_geometry, m)?)?;
    m.add_function(wrap_pyfunction!(polygon::polygon_wrench, m)?)?;
    m.add_function(wrap_pyfunction!(polygon::polygon_gauge, m)?)?;
    m.add_function(wrap_pyfunction!(ppod::asymptotic_field, m)?)?;
    m.add_function(wrap_pyfunction!(friction::force_table, m)?)?;
    m.add_function(wrap_pyfunction!(disk::disk_friction, m)?)?;
    m.add_function(wrap_pyfunction!(theory::theorem1_force, m)?)?;
    m.add_function(wrap_pyfunction!(theory::bang_bang_feed_rate, m)?)?;
    m.add_function(wrap_pyfunction!(theory::bang_bang_force, m)?)?;
    m.add_function(wrap_pyfunction!(theory::bang_bang_velocity_range, m)?)?;
    m.add_function(wrap_pyfunction!(theory::bang_bang_efficiency, m)?)?;
    m.add_function(wrap_pyfunction!(theory::viscous_gain, m)?)?;
    m.add_function(wrap_pyfunction!(theory::two_harmonic_feed_rate, m)?)?;
    m.add_function(wrap_pyfunction!(theory::two_harmonic_force_at_rest, m)?)?;
    m.add_function(wrap_pyfunction!(theory::gamma, m)?)?;
    m.add_function(wrap_pyfunction!(theory::normalized_drive, m)?)?;
    m.add_function(wrap_pyfunction!(_panic_for_test, m)?)?;
    Ok(())
}
