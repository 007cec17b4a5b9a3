//! Binding of `upm_core::simd`: which vector build runs here.

use pyo3::prelude::*;

/// How this build runs here: the point-part step's build chosen at run time (`UPM_SIMD`
/// overrides it) and the builds this CPU has.
#[pyfunction]
pub fn simd_info() -> (String, Vec<String>) {
    let names = |b: upm_core::simd::Simd| b.name().to_string();
    (
        names(upm_core::simd::simd()),
        upm_core::simd::Simd::available()
            .into_iter()
            .map(names)
            .collect(),
    )
}
