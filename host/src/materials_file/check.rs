//! A material checked against its model: the keys the model requires, forbids or takes as
//! 0 only, the values' ranges, and the kind of its lobe.

use relume_core::material::Kind;

use super::model::{Rule, KEYS};
use super::MaterialDesc;

impl MaterialDesc {
    /// Which keys are present, in [`KEYS`] order.
    fn present(&self) -> [bool; 7] {
        [
            self.color.is_some(),
            self.specularity.is_some(),
            self.roughness.is_some(),
            self.roughness_u.is_some(),
            self.roughness_v.is_some(),
            self.direction_u.is_some(),
            self.diffuse_map.is_some(),
        ]
    }

    /// Checks keys against the model and values against their ranges; the message names the
    /// group and the key.
    pub(crate) fn check(&self) -> Result<(), (usize, String)> {
        let g = &self.group;
        let model = self.model.name();
        let present = self.present();
        for (k, rule) in self.model.rules().into_iter().enumerate() {
            match (rule, present[k]) {
                (Rule::Required, false) => {
                    return Err((
                        k,
                        format!("group '{g}': model \"{model}\" needs `{}`", KEYS[k]),
                    ))
                }
                (Rule::Forbidden, true) => {
                    let why = if k == 0 && self.model.is_textured() {
                        " (a textured model stores the colour in diffuse_map)"
                    } else {
                        ""
                    };
                    return Err((
                        k,
                        format!("group '{g}': model \"{model}\" takes no `{}`{why}", KEYS[k]),
                    ));
                }
                _ => {}
            }
        }
        let zero = |k: usize, v: Option<f32>| {
            match (self.model.rules()[k], v) {
            (Rule::Zero, Some(x)) if x != 0.0 => Err((
                k,
                format!("group '{g}': model \"{model}\" has no specular part, so `{}` must be 0, got {x:?}", KEYS[k]),
            )),
            _ => Ok(()),
        }
        };
        zero(1, self.specularity)?;
        zero(2, self.roughness)?;
        if let Some(c) = self.color {
            if c.iter()
                .any(|x| !(x.is_finite() && (0.0..=1.0).contains(x)))
            {
                return Err((
                    0,
                    format!("group '{g}': color components must be in [0, 1], got {c:?}"),
                ));
            }
        }
        if let Some(s) = self.specularity {
            if !(s.is_finite() && (0.0..=1.0).contains(&s)) {
                return Err((
                    1,
                    format!("group '{g}': specularity must be in [0, 1], got {s:?}"),
                ));
            }
        }
        let rough = [
            (2, self.roughness),
            (3, self.roughness_u),
            (4, self.roughness_v),
        ];
        for (k, r) in rough {
            if let Some(r) = r {
                let must_be_zero = self.model.rules()[k] == Rule::Zero;
                let in_range = r.is_finite() && r > 0.0 && r <= 1.0;
                if !must_be_zero && !in_range {
                    return Err((
                        k,
                        format!("group '{g}': {} must be in (0, 1], got {r:?}", KEYS[k]),
                    ));
                }
            }
        }
        if let Some(d) = self.direction_u {
            if d.iter().any(|x| !x.is_finite()) || d == [0.0; 3] {
                return Err((
                    5,
                    format!("group '{g}': direction_u must be finite and not zero, got {d:?}"),
                ));
            }
        }
        match self.kind {
            Some(_) if !self.model.has_lobe() => Err((
                KIND_KEY,
                format!("group '{g}': model \"{model}\" has no lobe, so it takes no `kind`"),
            )),
            Some(Kind::Metal) if self.model.is_textured() => Err((
                KIND_KEY,
                format!(
                    "group '{g}': model \"{model}\" takes kind \"plastic\" only: textured models apply to plastic groups"
                ),
            )),
            _ => Ok(()),
        }
    }
}

/// The index that [`MaterialDesc::check`] gives a fault of `kind` (after [`KEYS`]).
const KIND_KEY: usize = KEYS.len();

#[cfg(test)]
mod tests {
    use super::*;
    use crate::materials_file::tests::{bad, body, file_text, line_of, write};
    use crate::materials_file::{kind_name, load_materials, Model};

    /// A lobe's kind loads where the model has a lobe (a textured one as plastic only),
    /// and is refused, at its line, on the others and when it is neither kind.
    #[test]
    fn kind_is_given_only_to_a_lobe() {
        for model in Model::ALL {
            for kind in [Kind::Plastic, Kind::Metal] {
                let line = format!("kind = \"{}\"\n", kind_name(kind));
                let text = file_text(model, &format!("{line}{}", body(model, None, None)));
                if model.has_lobe() && !(model.is_textured() && kind == Kind::Metal) {
                    let (_dir, path) = write(&text);
                    let m = load_materials(&path).unwrap_or_else(|e| panic!("{e}\n{text}"));
                    assert_eq!(m.materials[0].kind, Some(kind), "{model:?}");
                } else if model.has_lobe() {
                    bad(&text, 6, &["group 'g'", "takes kind \"plastic\" only"]);
                } else {
                    bad(&text, 6, &["group 'g'", model.name(), "takes no `kind`"]);
                }
            }
        }
        let text = file_text(
            Model::Isotropic,
            &format!("kind = \"gold\"\n{}", body(Model::Isotropic, None, None)),
        );
        bad(
            &text,
            6,
            &["group 'g'", "unknown kind 'gold'", "plastic or metal"],
        );
        let text = file_text(
            Model::Isotropic,
            &format!("kind = \"auto\"\n{}", body(Model::Isotropic, None, None)),
        );
        bad(
            &text,
            6,
            &[
                "group 'g'",
                "\"auto\" belongs in scene.toml",
                "plastic or metal",
            ],
        );
        let (_dir, path) = write(&file_text(
            Model::Isotropic,
            &body(Model::Isotropic, None, None),
        ));
        assert_eq!(load_materials(&path).unwrap().materials[0].kind, None);
    }

    #[test]
    fn required_keys_per_model() {
        for model in Model::ALL {
            for (k, rule) in model.rules().into_iter().enumerate() {
                if rule == Rule::Required {
                    let text = file_text(model, &body(model, Some(k), None));
                    bad(
                        &text,
                        3,
                        &["group 'g'", model.name(), &format!("needs `{}`", KEYS[k])],
                    );
                }
            }
        }
    }

    #[test]
    fn forbidden_keys_per_model() {
        for model in Model::ALL {
            for (k, rule) in model.rules().into_iter().enumerate() {
                if rule == Rule::Forbidden {
                    let text = file_text(model, &body(model, None, Some(k)));
                    bad(
                        &text,
                        line_of(&text, KEYS[k]),
                        &["group 'g'", &format!("takes no `{}`", KEYS[k])],
                    );
                }
            }
        }
        let text = file_text(
            Model::TexturedDiffuse,
            &body(Model::TexturedDiffuse, None, Some(0)),
        );
        bad(
            &text,
            6,
            &["textured model stores the colour in diffuse_map"],
        );
    }

    #[test]
    fn zero_keys_are_optional_and_must_be_zero() {
        for model in [Model::Diffuse, Model::TexturedDiffuse] {
            let text = file_text(model, &body(model, Some(1), None));
            let (_dir, path) = write(&text);
            load_materials(&path).unwrap();
            let text = text.replace("roughness = 0.0", "roughness = 0.1");
            bad(
                &text,
                line_of(&text, "roughness"),
                &["has no specular part", "`roughness` must be 0, got 0.1"],
            );
            // A value far from 1 is written with its exponent, not 47 digits.
            let tiny = text.replace("roughness = 0.1", "roughness = 1e-45");
            bad(
                &tiny,
                line_of(&tiny, "roughness"),
                &["`roughness` must be 0, got 1e-45"],
            );
            let text = file_text(model, &body(model, None, None))
                .replace("specularity = 0.0", "specularity = 0.2");
            bad(
                &text,
                line_of(&text, "specularity"),
                &["`specularity` must be 0"],
            );
        }
    }

    #[test]
    fn ranges() {
        let iso = file_text(Model::Isotropic, &body(Model::Isotropic, None, None));
        let aniso = file_text(Model::Anisotropic, &body(Model::Anisotropic, None, None));
        let cases: [(&str, &str, &str, &str); 12] = [
            (
                &iso,
                "color = [0.5, 0.4, 0.3]",
                "color = [0.5, 1.2, 0.3]",
                "color components must be in [0, 1]",
            ),
            (
                &iso,
                "color = [0.5, 0.4, 0.3]",
                "color = [-0.1, 0.4, 0.3]",
                "color components must be in [0, 1]",
            ),
            (
                &iso,
                "specularity = 0.05",
                "specularity = 1.5",
                "specularity must be in [0, 1], got 1.5",
            ),
            (
                &iso,
                "specularity = 0.05",
                "specularity = -0.5",
                "specularity must be in [0, 1]",
            ),
            (
                &iso,
                "roughness = 0.1",
                "roughness = 0.0",
                "roughness must be in (0, 1], got 0",
            ),
            (
                &iso,
                "roughness = 0.1",
                "roughness = 1e-50",
                "`roughness` is too small for a 32-bit float, which reads 1e-50 as 0",
            ),
            (
                &iso,
                "roughness = 0.1",
                "roughness = 1.5",
                "roughness must be in (0, 1]",
            ),
            (
                &aniso,
                "roughness_u = 0.05",
                "roughness_u = 0",
                "roughness_u must be in (0, 1]",
            ),
            (
                &aniso,
                "roughness_v = 0.2",
                "roughness_v = -1",
                "roughness_v must be in (0, 1]",
            ),
            (
                &aniso,
                "direction_u = [1.0, 0.0, 0.0]",
                "direction_u = [0, 0, 0]",
                "direction_u must be finite and not zero",
            ),
            (
                &iso,
                "roughness = 0.1",
                "roughness = nan",
                "`roughness` must be a finite number",
            ),
            (
                &aniso,
                "direction_u = [1.0, 0.0, 0.0]",
                "direction_u = [1.0, 0.0]",
                "`direction_u` must have 3 numbers",
            ),
        ];
        for (base, from, to, what) in cases {
            assert!(base.contains(from), "{from}");
            let text = base.replace(from, to);
            let key = to.split(' ').next().unwrap();
            bad(&text, line_of(&text, key), &[what]);
        }
        // Integers are numbers; roughness 1 is the upper end.
        let (_dir, path) = write(
            &iso.replace("roughness = 0.1", "roughness = 1")
                .replace("color = [0.5, 0.4, 0.3]", "color = [1, 0, 0]"),
        );
        let m = load_materials(&path).unwrap();
        assert_eq!(
            (m.materials[0].roughness, m.materials[0].color),
            (Some(1.0), Some([1.0, 0.0, 0.0]))
        );
        // A direction of any length is a direction: 1e-50 underflowed f32 and was refused
        // as zero.
        let (_dir, path) = write(&aniso.replace(
            "direction_u = [1.0, 0.0, 0.0]",
            "direction_u = [1e-50, 0.0, 0.0]",
        ));
        let d = load_materials(&path).unwrap().materials[0]
            .direction_u
            .unwrap();
        assert!((1.0..2.0).contains(&d[0]) && d[1..] == [0.0, 0.0], "{d:?}");
    }
}
