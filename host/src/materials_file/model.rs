//! The reflectance models of materials.toml and the keys each takes (the table in the
//! module's comment), and the names of a lobe's kind in the file.

use relume_core::material::Kind;

/// The reflectance model of a group.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Model {
    Diffuse,
    Isotropic,
    Anisotropic,
    Mirror,
    TexturedDiffuse,
    TexturedIsotropic,
    TexturedAnisotropic,
}

impl Model {
    pub const ALL: [Model; 7] = [
        Model::Diffuse,
        Model::Isotropic,
        Model::Anisotropic,
        Model::Mirror,
        Model::TexturedDiffuse,
        Model::TexturedIsotropic,
        Model::TexturedAnisotropic,
    ];

    /// The name in the file.
    pub fn name(self) -> &'static str {
        match self {
            Model::Diffuse => "diffuse",
            Model::Isotropic => "isotropic",
            Model::Anisotropic => "anisotropic",
            Model::Mirror => "mirror",
            Model::TexturedDiffuse => "textured-diffuse",
            Model::TexturedIsotropic => "textured-isotropic",
            Model::TexturedAnisotropic => "textured-anisotropic",
        }
    }

    pub fn from_name(s: &str) -> Option<Model> {
        Model::ALL.into_iter().find(|m| m.name() == s)
    }

    /// Whether a material of this model must give `key` (a materials.toml key, "color",
    /// "roughness_u", ...): the parameters it has.
    pub fn requires(self, key: &str) -> bool {
        KEYS.iter()
            .position(|k| *k == key)
            .is_some_and(|i| self.rules()[i] == Rule::Required)
    }

    /// Whether the model has a specular lobe, whose colour the kind decides.
    pub fn has_lobe(self) -> bool {
        matches!(
            self,
            Model::Isotropic
                | Model::Anisotropic
                | Model::TexturedIsotropic
                | Model::TexturedAnisotropic
        )
    }

    pub fn is_textured(self) -> bool {
        matches!(
            self,
            Model::TexturedDiffuse | Model::TexturedIsotropic | Model::TexturedAnisotropic
        )
    }

    /// The rule for each key, in [`KEYS`] order.
    pub(super) fn rules(self) -> [Rule; 7] {
        use Rule::{Forbidden as F, Required as R, Zero as Z};
        match self {
            //                          color spec rough ru rv dir map
            Model::Diffuse => [R, Z, Z, F, F, F, F],
            Model::Isotropic => [R, R, R, F, F, F, F],
            Model::Anisotropic => [R, R, F, R, R, R, F],
            Model::Mirror => [R, F, F, F, F, F, F],
            Model::TexturedDiffuse => [F, Z, Z, F, F, F, R],
            Model::TexturedIsotropic => [F, R, R, F, F, F, R],
            Model::TexturedAnisotropic => [F, R, F, R, R, R, R],
        }
    }
}

#[derive(Clone, Copy, PartialEq, Eq)]
pub(super) enum Rule {
    Required,
    /// Optional, and 0 when present.
    Zero,
    Forbidden,
}

/// The model-dependent keys, in the order they are written.
pub(super) const KEYS: [&str; 7] = [
    "color",
    "specularity",
    "roughness",
    "roughness_u",
    "roughness_v",
    "direction_u",
    "diffuse_map",
];

/// `kind`'s value in the file.
pub fn kind_name(kind: Kind) -> &'static str {
    match kind {
        Kind::Plastic => "plastic",
        Kind::Metal => "metal",
    }
}

pub(super) fn kind_from_name(name: &str) -> Option<Kind> {
    [Kind::Plastic, Kind::Metal]
        .into_iter()
        .find(|&k| kind_name(k) == name)
}
