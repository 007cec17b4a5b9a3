//! # upm-core
//!
//! Physics and numerics of vibratory planar manipulation: D. Reznik, *The Universal Planar
//! Manipulator* (PhD thesis, UC Berkeley, 2000). Pure Rust, no Python: the `upm-py` crate binds it.
//!
//! SI units throughout (m, s, rad); forces are averages over one period divided by `mu m g`
//! unless a name says otherwise. Equation numbers `(x.y)` refer to the thesis; `docs/spec.md §n` to the
//! project's clean restatement of it.
//!
//! * [`actuation`]: motors, wrench and centre of rotation; plate dynamics; harmonic fits and
//!   the accelerometer centre of rotation.
//! * [`waveform`]: periodic 1-D plate velocities and their monotone pieces.
//! * [`disk`]: friction force and torque of a flat disk, and its implicit stick–slip step.
//! * [`friction`]: exact average Coulomb forces and feed rates (root-based, no sampling).
//! * [`theory`]: the closed forms of chapter 3 and Theorem 1 (section 6.4).
//! * [`motion`]: plate motion programs `(u1, u2, u3)(t)`.
//! * [`sim`]: the exact stick–slip integrator for point and disk parts, batched and parallel;
//!   [`sim::contact`] resolves disk contacts with rapier2d.
//! * [`field`]: average force fields of rotations, jets and any plate motion.
//! * [`mchip`]: the M-Chip resonator array of chapter 2 (rapier3d).
//! * [`solve`]: the sequencing-rotations and displacement-field solvers (ordered); [`linalg`]: their
//!   least squares (SVD, damped, bounded).
//! * [`parallel`]: deterministic batches on rayon; [`simd`]: the vector build chosen at run time.
//! * [`stroke`]: the largest plate-corner excursion of many pulses at once.
//! * [`polygon`]: convex polygon parts and their exact friction wrench (docs/spec.md §11).
//! * [`ppod`]: velocity fields (drift and asymptotic) of a plate that moves out of its plane
//!   ([`motion::spatial`], docs/spec.md §10).
#![deny(missing_docs)]

pub mod actuation;
pub mod aligned;
pub mod buffer;
pub mod centroid;
pub mod disk;
pub mod error;
pub mod field;
pub mod friction;
pub mod linalg;
pub mod mchip;
pub mod motion;
pub mod parallel;
pub mod plan;
pub mod polygon;
pub mod ppod;
pub(crate) mod quadrature;
pub(crate) mod roots;
pub mod sim;
pub mod simd;
pub mod solve;
pub mod stroke;
pub mod theory;
pub mod waveform;

pub use error::{Error, Result};
pub use waveform::{BangBang, Harmonics, Waveform};
