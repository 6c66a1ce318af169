//! What recovery decides for a group: a value that the next stage consumes, and that the
//! outputs are written from.

use glam::Vec3;
use relume_core::material::{Kind, Material, Params, SurfaceMaterial};

use crate::materials_file::{MaterialDesc, Model};

/// The recovered model of one group.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum GroupModel {
    Diffuse {
        color: [f64; 3],
    },
    Isotropic {
        kind: Kind,
        color: [f64; 3],
        specularity: f64,
        roughness: f64,
    },
    Mirror {
        color: [f64; 3],
    },
    /// No pure pixel: nothing recovered (rendered as a neutral grey meanwhile).
    Unseen,
}

fn v3(c: [f64; 3]) -> Vec3 {
    Vec3::new(c[0] as f32, c[1] as f32, c[2] as f32)
}

impl GroupModel {
    pub fn name(&self) -> &'static str {
        match self {
            GroupModel::Diffuse { .. } => "diffuse",
            GroupModel::Isotropic { .. } => "isotropic",
            GroupModel::Mirror { .. } => "mirror",
            GroupModel::Unseen => "unseen",
        }
    }

    /// Diffuse and specular reflectances `(rho_d, rho_s)` (reflectance.md).
    pub fn reflectances(&self) -> ([f64; 3], [f64; 3]) {
        match *self {
            GroupModel::Diffuse { color } => (color, [0.0; 3]),
            GroupModel::Isotropic {
                kind,
                color,
                specularity: s,
                ..
            } => (
                color.map(|c| c * (1.0 - s)),
                match kind {
                    Kind::Plastic => [s; 3],
                    Kind::Metal => color.map(|c| c * s),
                },
            ),
            GroupModel::Mirror { color } => ([0.0; 3], color),
            GroupModel::Unseen => ([0.0; 3], [0.0; 3]),
        }
    }

    /// The material the renderer uses for this model.
    pub fn surface_material(&self) -> SurfaceMaterial {
        let material = match *self {
            GroupModel::Diffuse { color } => Material::Diffuse { rho_d: v3(color) },
            GroupModel::Isotropic {
                kind,
                color,
                specularity,
                roughness,
            } => Material::from_params(
                kind,
                v3(color),
                Params::Isotropic {
                    specularity: specularity as f32,
                    roughness: roughness as f32,
                },
            )
            .unwrap_or(Material::Diffuse { rho_d: v3(color) }),
            GroupModel::Mirror { color } => Material::Mirror { rho: v3(color) },
            GroupModel::Unseen => Material::Diffuse {
                rho_d: Vec3::splat(0.5),
            },
        };
        SurfaceMaterial {
            material,
            diffuse_map: None,
        }
    }

    /// The entry of materials.toml (none for an unseen group).
    pub fn material_desc(&self, group: &str) -> Option<MaterialDesc> {
        let f = |c: [f64; 3]| Some(c.map(|x| x as f32));
        let mut d = MaterialDesc::new(group, Model::Diffuse);
        match *self {
            GroupModel::Diffuse { color } => {
                d.color = f(color);
                d.specularity = Some(0.0);
                d.roughness = Some(0.0);
            }
            GroupModel::Isotropic {
                color,
                specularity,
                roughness,
                ..
            } => {
                d.model = Model::Isotropic;
                d.color = f(color);
                d.specularity = Some(specularity as f32);
                d.roughness = Some(roughness as f32);
            }
            GroupModel::Mirror { color } => {
                d.model = Model::Mirror;
                d.color = f(color);
            }
            GroupModel::Unseen => return None,
        }
        Some(d)
    }

    /// The RADIANCE primitive of this model.
    pub fn radiance_primitive(&self, group: &str) -> Option<String> {
        Some(match *self {
            GroupModel::Diffuse { color: c } => format!(
                "void plastic {group}\n0\n0\n5 {} {} {} 0 0\n",
                c[0] as f32, c[1] as f32, c[2] as f32
            ),
            GroupModel::Isotropic {
                kind,
                color: c,
                specularity,
                roughness,
            } => format!(
                "void {} {group}\n0\n0\n5 {} {} {} {} {}\n",
                if kind == Kind::Metal {
                    "metal"
                } else {
                    "plastic"
                },
                c[0] as f32,
                c[1] as f32,
                c[2] as f32,
                specularity as f32,
                roughness as f32
            ),
            GroupModel::Mirror { color: c } => format!(
                "void mirror {group}\n0\n0\n3 {} {} {}\n",
                c[0] as f32, c[1] as f32, c[2] as f32
            ),
            GroupModel::Unseen => return None,
        })
    }
}
