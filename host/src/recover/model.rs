//! What recovery decides for a group: a value that the next stage consumes, and that the
//! outputs are written from.

use glam::Vec3;
use std::path::Path;

use relume_core::material::{Kind, Material, Params, SurfaceMaterial, TextureId};

use crate::materials_file::{MaterialDesc, Model};

/// The diffuse colour an unseen group is rendered with until (or unless) one is measured:
/// a neutral grey, since nothing is known of it.
pub const NEUTRAL_STAND_IN: [f64; 3] = [0.5; 3];

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
    /// Stage 4: a Ward lobe of roughness `roughness_u` along `direction` (projected on
    /// the surface) and `roughness_v` across.
    Anisotropic {
        kind: Kind,
        color: [f64; 3],
        specularity: f64,
        roughness_u: f64,
        roughness_v: f64,
        direction: [f64; 3],
    },
    Mirror {
        color: [f64; 3],
    },
    /// A plastic whose diffuse reflectance is the recovered map `map` (an index into the
    /// recovery's maps), under the specular lobe `lobe` (stage 5: textured-diffuse,
    /// -isotropic or -anisotropic).
    Textured {
        map: usize,
        lobe: MapLobe,
    },
    /// No pure pixel (or no light reaching it): nothing recovered. The recovery still
    /// renders the group, whose light reaches the others, as the diffuse `stand_in`:
    /// `NEUTRAL_STAND_IN`, or a colour measured on the pixels it shares with seen
    /// groups (`unseen::measure_stand_ins`).
    Unseen {
        stand_in: [f64; 3],
    },
}

/// The white specular lobe of a textured plastic: the untextured stand-in's lobe, whose
/// diffuse colour the map replaces.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum MapLobe {
    None,
    Isotropic {
        specularity: f64,
        roughness: f64,
    },
    Anisotropic {
        specularity: f64,
        roughness_u: f64,
        roughness_v: f64,
        direction: [f64; 3],
    },
}

impl MapLobe {
    /// An isotropic lobe, or none when its specularity is none: a lobe refitted to zero
    /// (stage 5, the highlights explained by the map filled in from their neighbours)
    /// leaves the group textured-diffuse rather than textured-isotropic with no lobe.
    pub fn isotropic(specularity: f64, roughness: f64) -> MapLobe {
        if specularity > 0.0 {
            MapLobe::Isotropic {
                specularity,
                roughness,
            }
        } else {
            MapLobe::None
        }
    }

    /// The lobe of an untextured plastic stand-in (`None` for any other model).
    pub fn of_stand_in(model: &GroupModel) -> MapLobe {
        match *model {
            GroupModel::Isotropic {
                kind: Kind::Plastic,
                specularity,
                roughness,
                ..
            } => MapLobe::Isotropic {
                specularity,
                roughness,
            },
            GroupModel::Anisotropic {
                kind: Kind::Plastic,
                specularity,
                roughness_u,
                roughness_v,
                direction,
                ..
            } => MapLobe::Anisotropic {
                specularity,
                roughness_u,
                roughness_v,
                direction,
            },
            _ => MapLobe::None,
        }
    }

    /// The untextured plastic of colour `color` with this lobe: what a textured model is
    /// where its map reads `color (1 - specularity)`.
    pub fn with_color(&self, color: [f64; 3]) -> GroupModel {
        match *self {
            MapLobe::None => GroupModel::Diffuse { color },
            MapLobe::Isotropic {
                specularity,
                roughness,
            } => GroupModel::Isotropic {
                kind: Kind::Plastic,
                color,
                specularity,
                roughness,
            },
            MapLobe::Anisotropic {
                specularity,
                roughness_u,
                roughness_v,
                direction,
            } => GroupModel::Anisotropic {
                kind: Kind::Plastic,
                color,
                specularity,
                roughness_u,
                roughness_v,
                direction,
            },
        }
    }

    /// The file's model of a map under this lobe.
    pub fn textured_model(&self) -> Model {
        match self {
            MapLobe::None => Model::TexturedDiffuse,
            MapLobe::Isotropic { .. } => Model::TexturedIsotropic,
            MapLobe::Anisotropic { .. } => Model::TexturedAnisotropic,
        }
    }

    /// The white plastic with this lobe: under the map (which replaces its diffuse
    /// colour), what the textured model renders, writes and perturbs.
    pub fn white(&self) -> GroupModel {
        self.with_color([1.0; 3])
    }

    pub fn specularity(&self) -> f64 {
        match *self {
            MapLobe::None => 0.0,
            MapLobe::Isotropic { specularity, .. } | MapLobe::Anisotropic { specularity, .. } => {
                specularity
            }
        }
    }
}

/// How far a reflectance is from grey: `(max - min) / max` over the channels (1 for black).
/// The paper's mirror test wants the reflected colour close to the incident one.
pub fn tint(rho: [f64; 3]) -> f64 {
    let (lo, hi) = rho
        .iter()
        .fold((f64::INFINITY, 0.0f64), |(l, h), &v| (l.min(v), h.max(v)));
    if hi > 0.0 {
        (hi - lo) / hi
    } else {
        1.0
    }
}

fn v3(c: [f64; 3]) -> Vec3 {
    Vec3::new(c[0] as f32, c[1] as f32, c[2] as f32)
}

impl GroupModel {
    pub fn name(&self) -> &'static str {
        match self {
            GroupModel::Diffuse { .. } => "diffuse",
            GroupModel::Isotropic { .. } => "isotropic",
            GroupModel::Anisotropic { .. } => "anisotropic",
            GroupModel::Mirror { .. } => "mirror",
            GroupModel::Textured { lobe, .. } => lobe.textured_model().name(),
            GroupModel::Unseen { .. } => "unseen",
        }
    }

    /// Whether it reflects specularly at all: a Ward model of specularity 0 is the diffuse
    /// model of its colour, and is not kept as a lobe (a fit that renders better with one
    /// renders better by its colour, which the colour polish takes up).
    pub fn has_lobe(&self) -> bool {
        match self {
            GroupModel::Isotropic { .. } | GroupModel::Anisotropic { .. } => {
                self.reflectances().1.iter().any(|&r| r > 0.0)
            }
            GroupModel::Mirror { .. } => true,
            GroupModel::Textured { lobe, .. } => lobe.textured_model().has_lobe(),
            GroupModel::Diffuse { .. } | GroupModel::Unseen { .. } => false,
        }
    }

    /// The kind of its lobe (`None` without one; a textured model's lobe is a plastic's).
    pub fn lobe_kind(&self) -> Option<Kind> {
        match *self {
            GroupModel::Isotropic { kind, .. } | GroupModel::Anisotropic { kind, .. } => Some(kind),
            GroupModel::Textured { lobe, .. } if lobe.textured_model().has_lobe() => {
                Some(Kind::Plastic)
            }
            _ => None,
        }
    }

    /// Diffuse and specular reflectances `(rho_d, rho_s)` (reflectance.md); for a textured
    /// model `rho_d` is in its map and given here as zero.
    pub fn reflectances(&self) -> ([f64; 3], [f64; 3]) {
        match *self {
            GroupModel::Diffuse { color } => (color, [0.0; 3]),
            GroupModel::Isotropic {
                kind,
                color,
                specularity: s,
                ..
            }
            | GroupModel::Anisotropic {
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
            GroupModel::Textured { lobe, .. } => ([0.0; 3], [lobe.specularity(); 3]),
            GroupModel::Unseen { .. } => ([0.0; 3], [0.0; 3]),
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
            GroupModel::Anisotropic {
                kind,
                color,
                specularity,
                roughness_u,
                roughness_v,
                direction,
            } => Material::from_params(
                kind,
                v3(color),
                Params::Anisotropic {
                    specularity: specularity as f32,
                    roughness_u: roughness_u as f32,
                    roughness_v: roughness_v as f32,
                    direction: v3(direction),
                },
            )
            .unwrap_or(Material::Diffuse { rho_d: v3(color) }),
            GroupModel::Mirror { color } => Material::Mirror { rho: v3(color) },
            GroupModel::Textured { map, lobe } => {
                // The map replaces rho_d: the white plastic with the lobe, under the map.
                return SurfaceMaterial {
                    diffuse_map: Some(TextureId(map as u16)),
                    ..lobe.white().surface_material()
                };
            }
            GroupModel::Unseen { stand_in } => Material::Diffuse {
                rho_d: v3(stand_in),
            },
        };
        SurfaceMaterial {
            material,
            diffuse_map: None,
        }
    }

    /// The entry of materials.toml (none for an unseen group).
    /// `map_path` is where a textured model's map is written.
    pub fn material_desc(&self, group: &str, map_path: Option<&Path>) -> Option<MaterialDesc> {
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
            GroupModel::Anisotropic {
                color,
                specularity,
                roughness_u,
                roughness_v,
                direction,
                ..
            } => {
                d.model = Model::Anisotropic;
                d.color = f(color);
                d.specularity = Some(specularity as f32);
                d.roughness_u = Some(roughness_u as f32);
                d.roughness_v = Some(roughness_v as f32);
                d.direction_u = f(direction);
            }
            GroupModel::Mirror { color } => {
                d.model = Model::Mirror;
                d.color = f(color);
            }
            GroupModel::Textured { lobe, .. } => {
                // The stand-in's keys, the colour given by the map instead.
                d = lobe.white().material_desc(group, None)?;
                d.model = lobe.textured_model();
                d.color = None;
                d.diffuse_map = map_path.map(Path::to_path_buf);
            }
            GroupModel::Unseen { .. } => return None,
        }
        Some(d)
    }

    /// The RADIANCE primitive of this model under `modifier` (`void`, or for a textured
    /// model the name of its `colorpict` pattern, the picture being the map over (1 - s),
    /// which multiplies the white stand-in's colour).
    pub fn radiance_primitive(&self, group: &str, modifier: &str) -> Option<String> {
        Some(match *self {
            GroupModel::Diffuse { color: c } => format!(
                "{modifier} plastic {group}\n0\n0\n5 {} {} {} 0 0\n",
                c[0] as f32, c[1] as f32, c[2] as f32
            ),
            GroupModel::Isotropic {
                kind,
                color: c,
                specularity,
                roughness,
            } => format!(
                "{modifier} {} {group}\n0\n0\n5 {} {} {} {} {}\n",
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
            GroupModel::Anisotropic {
                kind,
                color: c,
                specularity,
                roughness_u,
                roughness_v,
                direction: d,
            } => format!(
                "{modifier} {} {group}\n4 {} {} {} .\n0\n6 {} {} {} {} {} {}\n",
                if kind == Kind::Metal {
                    "metal2"
                } else {
                    "plastic2"
                },
                d[0] as f32,
                d[1] as f32,
                d[2] as f32,
                c[0] as f32,
                c[1] as f32,
                c[2] as f32,
                specularity as f32,
                roughness_u as f32,
                roughness_v as f32
            ),
            GroupModel::Mirror { color: c } => format!(
                "{modifier} mirror {group}\n0\n0\n3 {} {} {}\n",
                c[0] as f32, c[1] as f32, c[2] as f32
            ),
            GroupModel::Textured { lobe, .. } => {
                return lobe.white().radiance_primitive(group, modifier)
            }
            GroupModel::Unseen { .. } => return None,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_lobe_refitted_to_no_specularity_is_no_lobe() {
        let refitted = MapLobe::isotropic(0.0, 0.005);
        assert_eq!(refitted, MapLobe::None);
        assert_eq!(refitted.textured_model(), Model::TexturedDiffuse);
        assert_eq!(
            MapLobe::isotropic(0.06, 0.08),
            MapLobe::Isotropic {
                specularity: 0.06,
                roughness: 0.08
            }
        );
    }

    /// A Ward fit of specularity 0 (a cache's closed form at its bound, on a panorama far
    /// too dim) renders as the diffuse model of its colour: no lobe to keep.
    #[test]
    fn a_ward_model_of_no_specularity_has_no_lobe() {
        for kind in [Kind::Plastic, Kind::Metal] {
            let iso = |specularity| GroupModel::Isotropic {
                kind,
                color: [0.001, 0.0002, 0.0001],
                specularity,
                roughness: 0.005,
            };
            assert!(!iso(0.0).has_lobe());
            assert!(iso(1e-6).has_lobe());
            let aniso = |specularity| GroupModel::Anisotropic {
                kind,
                color: [0.5; 3],
                specularity,
                roughness_u: 0.05,
                roughness_v: 0.2,
                direction: [0.0, 0.0, 1.0],
            };
            assert!(!aniso(0.0).has_lobe());
            assert!(aniso(0.9).has_lobe());
        }
        // A metal's lobe is its colour times s: black, it reflects nothing.
        let black_metal = GroupModel::Isotropic {
            kind: Kind::Metal,
            color: [0.0; 3],
            specularity: 0.9,
            roughness: 0.1,
        };
        assert!(!black_metal.has_lobe());
        assert!(GroupModel::Mirror { color: [0.9; 3] }.has_lobe());
        assert!(!GroupModel::Diffuse { color: [0.5; 3] }.has_lobe());
    }

    #[test]
    fn stage_4_and_5_models_write_valid_entries_and_primitives() {
        let aniso = GroupModel::Anisotropic {
            kind: Kind::Metal,
            color: [0.7, 0.7, 0.8],
            specularity: 0.9,
            roughness_u: 0.05,
            roughness_v: 0.2,
            direction: [0.0, 0.0, 1.0],
        };
        let d = aniso.material_desc("plate", None).unwrap();
        assert_eq!(d.model, Model::Anisotropic);
        assert_eq!((d.roughness_u, d.roughness_v), (Some(0.05), Some(0.2)));
        assert!(d.check().is_ok());
        let rad = aniso.radiance_primitive("plate", "void").unwrap();
        assert!(rad.starts_with("void metal2 plate\n4 0 0 1 .\n0\n6 0.7 0.7 0.8 0.9 0.05 0.2"));
        assert!(matches!(
            aniso.surface_material().material,
            Material::WardAnisotropic { .. }
        ));

        let map = Path::new("/out/textures/pic.exr");
        let textured = GroupModel::Textured {
            map: 2,
            lobe: MapLobe::Isotropic {
                specularity: 0.05,
                roughness: 0.08,
            },
        };
        let d = textured.material_desc("pic", Some(map)).unwrap();
        assert_eq!(d.model, Model::TexturedIsotropic);
        assert_eq!(d.diffuse_map.as_deref(), Some(map));
        assert_eq!((d.color, d.roughness), (None, Some(0.08)));
        assert!(d.check().is_ok());
        assert_eq!(textured.surface_material().diffuse_map, Some(TextureId(2)));
        let plain = GroupModel::Textured {
            map: 0,
            lobe: MapLobe::None,
        };
        let d = plain.material_desc("pic", Some(map)).unwrap();
        assert_eq!((d.model, d.roughness), (Model::TexturedDiffuse, Some(0.0)));
        assert!(d.check().is_ok());
        assert_eq!(
            textured.radiance_primitive("pic", "pict_pic").unwrap(),
            "pict_pic plastic pic\n0\n0\n5 1 1 1 0.05 0.08\n"
        );
        assert_eq!(
            plain.radiance_primitive("pic", "pict_pic").unwrap(),
            "pict_pic plastic pic\n0\n0\n5 1 1 1 0 0\n"
        );

        // Textured-anisotropic: the map under a white plastic2 lobe, in every output.
        let brushed = GroupModel::Textured {
            map: 1,
            lobe: MapLobe::Anisotropic {
                specularity: 0.06,
                roughness_u: 0.05,
                roughness_v: 0.2,
                direction: [0.0, 1.0, 0.0],
            },
        };
        assert_eq!(brushed.name(), "textured-anisotropic");
        let d = brushed.material_desc("pic", Some(map)).unwrap();
        assert_eq!(d.model, Model::TexturedAnisotropic);
        assert_eq!(
            (d.roughness_u, d.roughness_v, d.direction_u),
            (Some(0.05), Some(0.2), Some([0.0, 1.0, 0.0]))
        );
        assert_eq!((d.color, d.roughness), (None, None));
        assert!(d.check().is_ok());
        assert!(brushed
            .radiance_primitive("pic", "pict_pic")
            .unwrap()
            .starts_with("pict_pic plastic2 pic\n4 0 1 0 .\n0\n6 1 1 1 0.06 0.05 0.2"));
        let surface = brushed.surface_material();
        assert_eq!(surface.diffuse_map, Some(TextureId(1)));
        assert!(matches!(
            surface.material,
            Material::WardAnisotropic { rho_s, .. } if rho_s == Vec3::splat(0.06)
        ));
        // The stand-in's lobe is what the textured model keeps.
        assert_eq!(
            MapLobe::of_stand_in(
                &MapLobe::Anisotropic {
                    specularity: 0.06,
                    roughness_u: 0.05,
                    roughness_v: 0.2,
                    direction: [0.0, 1.0, 0.0],
                }
                .with_color([0.3, 0.4, 0.5])
            ),
            match brushed {
                GroupModel::Textured { lobe, .. } => lobe,
                _ => unreachable!(),
            }
        );
    }
}
