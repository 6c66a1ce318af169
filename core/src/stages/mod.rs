//! The staged recovery of Sun & Wu (2003), one module per stage. Each stage is a pure
//! function of the fits the host measured (renders are the host's business, since they are
//! parallel), returning a value the next stage consumes.

pub mod diffuse;
pub mod isotropic;
pub mod texture;
pub mod texture_map;
