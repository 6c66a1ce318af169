//! The staged recovery of Sun & Wu (2003), one module per stage. Each stage is a pure
//! function of the fits the host measured (renders are the host's business, since they are
//! parallel), returning a value the next stage consumes.
//!
//! 1. [`diffuse`]: the ratio update `rho_d <- rho_d * mean(real) / mean(rendered)` and its verdict.
//! 2. [`isotropic`]: a Ward lobe's reflectances in closed form, its roughness searched.
//! 3. [`texture`]: is what the uniform model leaves a picture?
//! 4. [`anisotropic`]: an anisotropic lobe's shape searched, its reflectances in closed form.
//! 5. [`texture_map`]: a textured group's diffuse map under its lobe.

pub mod anisotropic;
pub mod diffuse;
pub mod isotropic;
pub mod texture;
pub mod texture_map;
