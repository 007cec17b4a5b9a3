//! The vector instructions a kernel is built for, chosen once at run time.
//!
//! Every vectorised kernel of the crate (the point-part step in `sim::kernel`, the one-pass short
//! runs, the lift-off step, the disks' sliding solves in `disk::lanes`, the polygon steps in
//! `polygon::lanes` and `polygon::four`, the stroke's corner excursions) has an AVX-512, an AVX2
//! and a portable build, and takes the one [`simd`] reports: chosen by CPU feature detection
//! (never by `target-cpu`), or by `UPM_SIMD=portable|avx2|avx512` in the environment (a build the
//! CPU lacks falls back to the best it has). One machine always takes the same build, so results
//! are bitwise identical for any thread count.

/// A build of the vector kernels.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Simd {
    /// Plain Rust, correctly rounded square root and division.
    Portable,
    /// AVX2 and FMA, four parts per instruction.
    Avx2,
    /// AVX-512F, eight parts per instruction.
    Avx512,
}

impl Simd {
    /// The build's name, as `UPM_SIMD` spells it.
    pub fn name(self) -> &'static str {
        match self {
            Simd::Portable => "portable",
            Simd::Avx2 => "avx2",
            Simd::Avx512 => "avx512",
        }
    }

    /// The builds this CPU can run, best last.
    pub fn available() -> Vec<Simd> {
        let mut out = vec![Simd::Portable];
        #[cfg(target_arch = "x86_64")]
        {
            if is_x86_feature_detected!("avx2") && is_x86_feature_detected!("fma") {
                out.push(Simd::Avx2);
            }
            if is_x86_feature_detected!("avx512f") {
                out.push(Simd::Avx512);
            }
        }
        out
    }
}

/// The build every simulation on this machine takes: `UPM_SIMD` if set to a build the CPU has,
/// else the best the CPU has (read once).
pub fn simd() -> Simd {
    static CHOSEN: std::sync::OnceLock<Simd> = std::sync::OnceLock::new();
    *CHOSEN.get_or_init(|| {
        let have = Simd::available();
        let best = *have.last().expect("portable is always available");
        match std::env::var("UPM_SIMD") {
            Ok(want) => have
                .iter()
                .copied()
                .find(|b| b.name() == want.trim().to_ascii_lowercase())
                .unwrap_or(best),
            Err(_) => best,
        }
    })
}
