//! relume-core: the allocation-free, `#![no_std]` heart of relume.
//!
//! Layers, bottom to top (a module only uses the ones above it in this list):
//!
//! - [`config`]: every capacity, named once.
//! - [`math`], [`rng`]: the one math backend (libm) and seeded random streams.
//! - [`geometry`]: rays, triangles, surfaces, views (pixel to ray, per the scene format).
//! - [`bvh`]: SAH bounding volume hierarchy over lent buffers; closest-hit and any-hit.
//! - [`material`]: the closed set of reflectance models (Ward isotropic/anisotropic, mirror,
//!   textures) with `eval` / `sample` / `pdf` in a local shading frame.
//! - [`scene`]: the assembled scene (triangles, BVH, materials, lights, textures), all lent
//!   by the caller and checked against the capacities.
//! - [`strata`]: where in a pixel its samples fall (scrambled Sobol', two halves).
//! - [`render`]: the path tracer (next-event estimation with multiple importance sampling).
//! - [`transport`]: the light at each pixel sample's first vertex, cached for re-weighting.
//! - [`fit`]: the fit error of a group and every threshold of the staged recovery.
//! - [`anneal`]: seeded simulated annealing in ask/tell form.
//! - [`nelder_mead`]: bounded Nelder-Mead simplex search in the same form (a local arm).
//! - [`stages`]: the stages of the recovery, as pure functions of measured fits.
//!
//! The core never allocates, never does I/O and never panics on user data: the host lends
//! buffers, the seed and the data, and gets values or [`Error`]s back.
#![no_std]
#![deny(unused_crate_dependencies)]
#![forbid(unsafe_code)]
// `!(x > 0.0)` is the core's idiom for "not a positive number, NaN included": the
// negated comparison is the point, not an accident.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

#[cfg(test)]
extern crate std;

// heapless is part of the core's toolbox for fixed-capacity containers; keep the
// dependency declared and linked even where a module does not yet need it.
use heapless as _;

pub mod anneal;
pub mod bvh;
pub mod config;
pub mod error;
pub mod fit;
pub mod geometry;
pub mod material;
pub mod math;
pub mod nelder_mead;
pub mod render;
pub mod rng;
pub mod scene;
pub mod stages;
pub mod strata;
pub mod student_t;
pub mod transport;

pub use error::Error;
