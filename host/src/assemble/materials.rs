//! The groups' materials as assembled: each group's material from the materials files
//! (its kind, its diffuse map as a texture of the core), and the texture coordinates a
//! map needs.

use std::path::{Path, PathBuf};

use glam::Vec3;
use relume_core::material::{
    Kind, Material, SurfaceMaterial, TextureGrid, TextureId, TextureInfo, Wrap,
};

use crate::error::Error;
use crate::fsutil;
use crate::images;
use crate::materials_file::{self, MaterialDesc, MaterialsDesc, Model};
use crate::obj::ObjObject;
use crate::scene_file::{GroupDesc, GroupKind, SceneDesc};

/// The kind scene.toml gives group `group` (`None` for a group it does not have).
fn kind_of(desc: &SceneDesc, group: &str) -> Option<GroupKind> {
    desc.groups.iter().find(|g| g.name == group).map(|g| g.kind)
}

/// The first object of `group` in the scene (not hidden) without texture coordinates on
/// every face, which a diffuse map needs: without them every point would read the map at
/// (0, 0), one texel for the whole object.
pub fn unmapped_object<'a>(
    desc: &SceneDesc,
    objects: &'a [ObjObject],
    group: &GroupDesc,
) -> Option<&'a ObjObject> {
    objects.iter().find(|o| {
        o.uvs.is_none() && !desc.hide.contains(&o.name) && group.objects.contains(&o.name)
    })
}

/// A group whose material has a diffuse map is mapped by its OBJ texture coordinates: each
/// of its objects must have them ([`unmapped_object`]).
pub(super) fn check_texture_coordinates(
    desc: &SceneDesc,
    objects: &[ObjObject],
    materials: &[SurfaceMaterial],
) -> Result<(), Error> {
    for (g, material) in desc.groups.iter().zip(materials) {
        if material.diffuse_map.is_none() {
            continue;
        }
        if let Some(o) = unmapped_object(desc, objects, g) {
            let what = format!(
                "object '{}' of group '{}' has no texture coordinates (vt on every face), but the group's material has a diffuse_map",
                o.name, g.name
            );
            return Err(match crate::obj::object_line(&o.file, &o.name) {
                Some(line) => Error::at_line(&o.file, line, what),
                None => Error::input(&o.file, what),
            });
        }
    }
    Ok(())
}

/// The kind a group's material `m` (from `file`) is rendered with: the scene's, or for a
/// group of kind "auto" the one the material gives (a recovery writes the kind it chose);
/// either without a lobe, whose reflectance does not depend on it. A material whose kind
/// contradicts the scene's, or a lobe with no kind from either, is an error at its line.
fn material_kind(desc: &SceneDesc, file: &MaterialsDesc, m: &MaterialDesc) -> Result<Kind, Error> {
    let scene_kind = kind_of(desc, &m.group).and_then(GroupKind::given);
    match (scene_kind, m.kind) {
        (Some(s), Some(k)) if s != k => Err(Error::at_line(
            &file.path,
            m.line,
            format!(
                "group '{}' is kind \"{}\" in {}, but its material says kind \"{}\"",
                m.group,
                materials_file::kind_name(s),
                desc.path.display(),
                materials_file::kind_name(k)
            ),
        )),
        (Some(kind), _) | (None, Some(kind)) => Ok(kind),
        (None, None) if !m.model.has_lobe() => Ok(Kind::Plastic),
        (None, None) => Err(Error::at_line(
            &file.path,
            m.line,
            format!(
                "group '{}' has kind \"auto\" in {}: a material with a lobe needs its kind, `kind = \"plastic\"` or `kind = \"metal\"` in the material (a recovery writes the kind it chose)",
                m.group,
                desc.path.display()
            ),
        )),
    }
}

/// The texture of the diffuse map `map` (`context` names the material that gives it, for
/// a capacity error): read, checked and appended to `texture_infos` and `texels` the first
/// time, and found in `maps_read` after that. A map that groups share is held once: a
/// 6000x6000 map on the floor and the ceiling was counted twice against MAX_TEXELS, and
/// refused.
fn map_texture(
    map: &Path,
    wrap: Wrap,
    context: impl Fn() -> String,
    maps_read: &mut Vec<(PathBuf, TextureId)>,
    texture_infos: &mut Vec<TextureInfo>,
    texels: &mut Vec<Vec3>,
) -> Result<TextureId, Error> {
    let info_of = |id: &TextureId| texture_infos[id.0 as usize];
    if let Some(&(_, id)) = maps_read
        .iter()
        .find(|(p, id)| fsutil::same_file(p, map) && info_of(id).grid.wrap == wrap)
    {
        return Ok(id);
    }
    // Read before with the other wrap (tiled on one group, clamped on another): the same
    // texels, read another way.
    if let Some((_, read)) = maps_read.iter().find(|(p, _)| fsutil::same_file(p, map)) {
        let first = info_of(read);
        let info = TextureInfo {
            grid: TextureGrid { wrap, ..first.grid },
            ..first
        };
        let id = push_texture_info(info, &context, map, texture_infos)?;
        maps_read.push((map.to_path_buf(), id));
        return Ok(id);
    }
    // Its size is weighed against the texels left before it is decoded.
    let image = images::read_map(map, texels.len(), &context)?;
    // A map holds diffuse reflectances, which `color` bounds by 1 as well.
    images::reject_value(
        map,
        &image,
        |v| v > 1.0,
        "is above 1: a diffuse map holds reflectances in [0, 1]",
    )?;
    let info = TextureInfo {
        grid: TextureGrid {
            width: image.width,
            height: image.height,
            wrap,
        },
        offset: texels.len(),
    };
    let id = push_texture_info(info, &context, map, texture_infos)?;
    texels.extend(image.pixels.iter().map(|p| Vec3::from(*p)));
    maps_read.push((map.to_path_buf(), id));
    Ok(id)
}

/// Appends `info` to `texture_infos`, within the core's `MAX_TEXTURES`.
fn push_texture_info(
    info: TextureInfo,
    context: impl Fn() -> String,
    map: &Path,
    texture_infos: &mut Vec<TextureInfo>,
) -> Result<TextureId, Error> {
    if texture_infos.len() >= relume_core::config::MAX_TEXTURES {
        return Err(Error::core(
            format!("{}: {}", context(), map.display()),
            relume_core::Error::Capacity {
                what: "MAX_TEXTURES",
                max: relume_core::config::MAX_TEXTURES,
                needed: texture_infos.len() + 1,
            },
        ));
    }
    texture_infos.push(info);
    Ok(TextureId((texture_infos.len() - 1) as u16))
}

/// One material per group, from one or more files: an error names the group and the
/// file(s) when a group has none or two, or when a file names a group the scene lacks.
pub(super) fn resolve_materials(
    desc: &SceneDesc,
    files: &[MaterialsDesc],
    texture_infos: &mut Vec<TextureInfo>,
    texels: &mut Vec<Vec3>,
) -> Result<Vec<SurfaceMaterial>, Error> {
    // The maps read so far, by the file they came from.
    let mut maps_read: Vec<(PathBuf, TextureId)> = Vec::new();
    let mut found: Vec<Option<(PathBuf, usize, SurfaceMaterial)>> = vec![None; desc.groups.len()];
    for file in files {
        for m in &file.materials {
            let Some(gi) = desc.groups.iter().position(|g| g.name == m.group) else {
                return Err(Error::at_line(
                    &file.path,
                    m.line,
                    format!(
                        "material for group '{}', which scene {} does not have",
                        m.group,
                        desc.path.display()
                    ),
                ));
            };
            if let Some((other, other_line, _)) = &found[gi] {
                return Err(Error::at_line(
                    &file.path,
                    m.line,
                    format!(
                        "group '{}' has two materials: here and at {}:{}",
                        m.group,
                        other.display(),
                        other_line
                    ),
                ));
            }
            let kind = material_kind(desc, file, m)?;
            let textured = matches!(
                m.model,
                Model::TexturedDiffuse | Model::TexturedIsotropic | Model::TexturedAnisotropic
            );
            let diffuse_map = if textured {
                let Some(map) = &m.diffuse_map else {
                    return Err(Error::at_line(
                        &file.path,
                        m.line,
                        "textured material without diffuse_map",
                    ));
                };
                if kind == Kind::Metal {
                    return Err(Error::at_line(
                        &file.path,
                        m.line,
                        format!(
                            "group '{}' is metal: textured models apply to plastic groups",
                            m.group
                        ),
                    ));
                }
                Some(map_texture(
                    map,
                    m.map_wrap,
                    || format!("{}:{}: group '{}'", file.path.display(), m.line, m.group),
                    &mut maps_read,
                    texture_infos,
                    texels,
                )?)
            } else {
                None
            };
            let material = Material::from_params(kind, Vec3::from(m.color_or_white()), m.params())
                .map_err(|e| {
                    Error::at_line(&file.path, m.line, format!("group '{}': {e}", m.group))
                })?;
            found[gi] = Some((
                file.path.clone(),
                m.line,
                SurfaceMaterial {
                    material,
                    diffuse_map,
                },
            ));
        }
    }
    let mut out = Vec::with_capacity(found.len());
    for (gi, f) in found.into_iter().enumerate() {
        match f {
            Some((_, _, m)) => out.push(m),
            None => {
                let names: Vec<String> =
                    files.iter().map(|f| f.path.display().to_string()).collect();
                let group = &desc.groups[gi];
                return Err(Error::at_line(
                    &desc.path,
                    group.line,
                    format!(
                        "group '{}' has no material in {}",
                        group.name,
                        names.join(", ")
                    ),
                ));
            }
        }
    }
    Ok(out)
}

/// How far past [0, 1] a texture coordinate may reach, from an exporter's rounding,
/// before it is taken to mean tiles.
const UV_SLACK: f32 = 1e-3;

/// Whether texture coordinate `(u, v)` lies past [0, 1]^2 by more than `UV_SLACK`: a
/// texture laid over its face as tiles (OpenGL's and the exporters' reading).
pub fn past_the_unit_square([u, v]: [f32; 2]) -> bool {
    let past = |x: f32| !(-UV_SLACK..=1.0 + UV_SLACK).contains(&x);
    past(u) || past(v)
}
