//! What a RADIANCE user is given beside materials.toml: materials.rad (every group's
//! model as a primitive, the lights, each picture as a colorpict), each textured group's
//! picture (`.hdr`) and mapping (`.cal`), a curved textured group's faces for obj2mesh,
//! and materials.map, obj2rad's rules naming each OBJ object after its primitive.

use std::collections::HashSet;
use std::path::{Path, PathBuf};

use relume_core::geometry::{Surface, Triangle};
use relume_core::material::Wrap;

use super::super::model::GroupModel;
use super::super::{texture, Recovery};
use super::{MATERIALS_MAP, MATERIALS_RAD, MESHES_DIR, TEXTURES_DIR};
use crate::error::Error;
use crate::fsutil::OutputSet;
use crate::images::{self, Image};
use crate::obj::ObjObject;
use crate::scene_file::{identifier_char, SceneDesc};

/// Adds every textured group's map (`textures/<group>.exr`) and what RADIANCE is given:
/// materials.rad, each picture's `.hdr` and `.cal`, a curved group's mesh
/// (`meshes/<group>.obj`) and materials.map, obj2rad's rules.
pub(super) fn add_maps_and_radiance(
    set: &mut OutputSet,
    out: &Path,
    rec: &Recovery,
    obj2rad: &Obj2radNames,
) -> Result<(), Error> {
    let names = &rec.owned.group_names;
    // The textured groups whose (u, v) RADIANCE reads on a mesh: materials.map leaves
    // their objects to it.
    let mut on_mesh = Vec::new();
    let mut rad = String::from("# relume: recovered materials as RADIANCE primitives\n");
    for (g, model) in rec.models.iter().enumerate() {
        let name = &names[g];
        // What RADIANCE is given: the model itself, under the modifier of its map when
        // it has one, and after it the mesh of a curved group.
        let mut primitive = (*model, String::from("void"));
        let mut after = String::new();
        if let GroupModel::Textured { map, lobe } = *model {
            set.create_dir(&out.join(TEXTURES_DIR))?;
            let map = &rec.maps[map];
            let image = Image {
                width: map.side,
                height: map.side,
                pixels: map.texels.iter().map(|t| t.to_array()).collect(),
            };
            let exr = out.join(TEXTURES_DIR).join(format!("{name}.exr"));
            images::add_exr(set, &exr, &image)?;
            let affine = texture::uv_affine(rec, g);
            let placement = match &affine {
                Some(affine) => Placement::Affine(affine, rec.owned.origin),
                None => {
                    // Curved: its (u, v) are no affine function of the hit point, which
                    // is all a picture on obj2rad's polygons can be given. An obj2mesh
                    // mesh keeps the OBJ's (u, v), which a .cal reads as Lu and Lv.
                    set.create_dir(&out.join(MESHES_DIR))?;
                    let triangles = rec
                        .owned
                        .triangles()
                        .iter()
                        .filter(|t| t.surface == Surface::Group(g as u16));
                    let obj = mesh_obj(name, triangles, rec.owned.origin);
                    set.add(&mesh_path(out, name, "obj"), obj.as_bytes())?;
                    on_mesh.push(g);
                    rad.push_str(&format!(
                        "\n# {name}: its texture coordinates are not an affine function of the surface point (a curved group),\n\
                         # so RADIANCE reads them on a mesh: meshes/{name}.obj holds its faces (materials.map leaves them out\n\
                         # of obj2rad's polygons). Before oconv, make the mesh in this folder, again after every recovery\n\
                         # (the mesh keeps the materials it was made with; a recovery removes an earlier one):\n\
                         #   obj2mesh -a materials.rad meshes/{name}.obj meshes/{name}.rtm\n"
                    ));
                    after = format!("\nvoid mesh {name}.mesh\n1 meshes/{name}.rtm\n0\n0\n");
                    Placement::Mesh
                }
            };
            let picture = Picture {
                map: &image,
                wrap: map.wrap,
                specularity: lobe.specularity(),
            };
            add_radiance_picture(set, out, name, picture, placement)?;
            primitive.1 = pattern_name(name, names);
            rad.push_str(&format!(
                "\nvoid colorpict {}\n7 red green blue textures/{name}.hdr textures/{name}.cal pic_u pic_v\n0\n0\n",
                primitive.1
            ));
        }
        // Unseen: the stand-in the recovery rendered it with (unseen.toml), so that the
        // scene loads (oconv stopped at "undefined modifier" for a group of no primitive).
        if let GroupModel::Unseen { stand_in } = primitive.0 {
            let [r, g, b] = stand_in;
            rad.push_str(&format!(
                "\n# {name}: unseen, not recovered; the diffuse stand-in [{r:.4} {g:.4} {b:.4}] the recovery rendered it with (unseen.toml, report.json)\n"
            ));
            primitive.0 = GroupModel::Diffuse { color: stand_in };
        }
        if let GroupModel::Mirror { .. } = primitive.0 {
            rad.push_str(&format!(
                "\n# {name}: RADIANCE's mirror reflects from its front only (where its vertices turn counter-clockwise) and is black from behind; relume's from both sides\n"
            ));
        }
        // Every model has a primitive now (an unseen group's stand-in is a diffuse).
        if let Some(p) = primitive.0.radiance_primitive(name, &primitive.1) {
            rad.push('\n');
            rad.push_str(&p);
        }
        rad.push_str(&after);
    }
    rad.push_str(&light_primitives(&rec.owned.desc, names));
    set.add(&out.join(MATERIALS_RAD), rad.as_bytes())?;
    set.add(
        &out.join(MATERIALS_MAP),
        obj2rad_map(&rec.owned.desc, names, &on_mesh, obj2rad).as_bytes(),
    )
}

/// `meshes/<group>.<extension>`: a curved group's faces (`obj`), or the mesh obj2mesh
/// makes of them (`rtm`).
pub(super) fn mesh_path(out: &Path, name: &str, extension: &str) -> PathBuf {
    out.join(MESHES_DIR).join(format!("{name}.{extension}"))
}

/// A curved group's faces as an OBJ for obj2mesh: in the scene's own coordinates (its
/// triangles are placed relative to `origin`), each corner with its texture coordinates,
/// all under `usemtl <group>`, which `obj2mesh -a materials.rad` binds to the group's
/// primitive.
fn mesh_obj<'a>(
    name: &str,
    triangles: impl Iterator<Item = &'a Triangle>,
    origin: [f64; 3],
) -> String {
    // A coordinate as the OBJ gave it where 32 bits hold it (a scene near its origin),
    // else in 64.
    let coordinate = |c: f64| {
        if f64::from(c as f32) == c {
            format!("{}", c as f32)
        } else {
            format!("{c}")
        }
    };
    let mut text = format!(
        "# relume: the faces of group {name}, whose texture coordinates obj2mesh keeps (RADIANCE's Lu, Lv):\n\
         #   obj2mesh -a materials.rad meshes/{name}.obj meshes/{name}.rtm\n\
         usemtl {name}\n"
    );
    for (i, t) in triangles.enumerate() {
        for (v, uv) in t.v.iter().zip(&t.uv) {
            let c = [v.x, v.y, v.z];
            let [x, y, z] =
                std::array::from_fn(|axis| coordinate(origin[axis] + f64::from(c[axis])));
            text.push_str(&format!("v {x} {y} {z}\nvt {} {}\n", uv.x, uv.y));
        }
        let k = 3 * i + 1;
        text.push_str(&format!(
            "f {k}/{k} {}/{} {}/{}\n",
            k + 1,
            k + 1,
            k + 2,
            k + 2
        ));
    }
    text
}

/// The names of the lights' primitives in materials.rad, in the scene's order of lights:
/// `light_<object>` with every character a RADIANCE identifier cannot hold made `_` (an
/// object `ceiling lamp` gave `void light light_ceiling lamp`, which oconv cannot read),
/// made longer while a group or an earlier light has that name.
fn light_names(desc: &SceneDesc, groups: &[String]) -> Vec<String> {
    let mut names: Vec<String> = Vec::with_capacity(desc.lights.len());
    for light in &desc.lights {
        let word: String = (light.object.chars())
            .map(|c| if identifier_char(c) { c } else { '_' })
            .collect();
        let mut name = format!("light_{word}");
        while groups.contains(&name) || names.contains(&name) {
            name.insert(0, '_');
        }
        names.push(name);
    }
    names
}

/// The scene's lights as RADIANCE `light` primitives (radiance in W sr^-1 m^-2 per channel,
/// as scene.toml gives it), so that materials.rad with the geometry is a whole scene.
fn light_primitives(desc: &SceneDesc, groups: &[String]) -> String {
    let mut text = String::new();
    for (light, name) in desc.lights.iter().zip(light_names(desc, groups)) {
        if desc.hide.contains(&light.object) {
            continue;
        }
        let [r, g, b] = light.radiance;
        text.push_str(&format!(
            "\n# light '{}' as scene.toml declares it\nvoid light {name}\n0\n0\n3 {r} {g} {b}\n",
            light.object
        ));
    }
    text
}

/// How RADIANCE's obj2rad names the scene's OBJ objects, for materials.map's rules: by the
/// first word of an `o` statement, or as a group where a file names its objects by `g`.
#[derive(Default)]
pub(in crate::recover) struct Obj2radNames {
    /// Objects named by `g` (their files have no `o`): `(Group "name")`.
    named_by_g: std::collections::HashSet<String>,
}

impl Obj2radNames {
    /// The names of `objects`, and a warning for each object of a group or a light whose
    /// name obj2rad cannot match (it holds a space or a quote), naming its file and line.
    pub(in crate::recover) fn new(
        desc: &SceneDesc,
        objects: &[ObjObject],
    ) -> (Obj2radNames, Vec<String>) {
        // The names the scene gives a material, gathered once (searched in every group's
        // list for each object, 30,000 objects took a second).
        let hidden: HashSet<&str> = desc.hide.iter().map(String::as_str).collect();
        let given: HashSet<&str> = (desc.groups.iter().flat_map(|g| &g.objects))
            .chain(desc.lights.iter().map(|l| &l.object))
            .map(String::as_str)
            .collect();
        let used = |name: &String| !hidden.contains(name.as_str()) && given.contains(name.as_str());
        let mut warnings = Vec::new();
        for o in objects.iter().filter(|o| used(&o.name)) {
            if !Self::matchable(&o.name) {
                warnings.push(format!(
                    "object '{}' ({}, line {}): RADIANCE's obj2rad names an object by one word, so materials.map cannot give it its material and obj2rad would leave its faces out; name it in one word without quotes to render the recovered scene in RADIANCE",
                    o.name,
                    o.file.display(),
                    o.line
                ));
            }
        }
        let named_by_g = (objects.iter())
            .filter(|o| o.named_by_g)
            .map(|o| o.name.clone())
            .collect();
        (Obj2radNames { named_by_g }, warnings)
    }

    /// Whether obj2rad reads `name` whole: one word, and no quote to end its string.
    fn matchable(name: &str) -> bool {
        !name.is_empty() && !name.contains(|c: char| c.is_whitespace() || c == '"')
    }

    /// The rule's qualifier for `object`, `None` where no rule can match it.
    fn qualifier(&self, object: &str) -> Option<&'static str> {
        match (Self::matchable(object), self.named_by_g.contains(object)) {
            (false, _) => None,
            (true, true) => Some("Group"),
            (true, false) => Some("Object"),
        }
    }
}

/// obj2rad's mapping rules: `obj2rad -m materials.map geometry.obj > geometry.rad` names
/// each object's faces after its group's primitive in materials.rad, or its light's
/// (without it, obj2rad names faces by `usemtl`, `g`, or "white"). Hidden objects are
/// no part of the recovered scene and get no rule. The objects of the groups `on_mesh`
/// (by index) are obj2mesh's, as `meshes/<group>.obj`: their rule is `void`, which obj2rad
/// skips, so that their faces are not polygons as well.
fn obj2rad_map(
    desc: &SceneDesc,
    groups: &[String],
    on_mesh: &[usize],
    obj2rad: &Obj2radNames,
) -> String {
    let mut text = String::from(
        "# relume: obj2rad -m materials.map <geometry.obj> > geometry.rad names each object's faces\n\
         # after its group's material in materials.rad; then oconv materials.rad geometry.rad\n",
    );
    let shown = |object: &&String| !desc.hide.contains(*object);
    let rule = |text: &mut String, modifier: &str, object: &str| match obj2rad.qualifier(object) {
        Some(q) => text.push_str(&format!("{modifier} ({q} \"{object}\") ;\n")),
        None => text.push_str(&format!(
            "# {modifier}: object {object:?} has no rule: obj2rad names objects by one word\n"
        )),
    };
    for (g, group) in desc.groups.iter().enumerate() {
        let modifier = if on_mesh.contains(&g) {
            text.push_str(&format!(
                "# {}: its faces are the mesh meshes/{}.rtm (obj2mesh, materials.rad), not polygons\n",
                group.name, group.name
            ));
            "void"
        } else {
            group.name.as_str()
        };
        for object in group.objects.iter().filter(shown) {
            rule(&mut text, modifier, object);
        }
    }
    for (light, name) in desc.lights.iter().zip(light_names(desc, groups)) {
        if shown(&&light.object) {
            rule(&mut text, &name, &light.object);
        }
    }
    text
}

/// The name of group `name`'s picture pattern in materials.rad: `pict_<name>`, made longer
/// while a group has that name (RADIANCE binds a name to its last definition, and the
/// group `pict_X` rendered X's surfaces invisible).
fn pattern_name(name: &str, groups: &[String]) -> String {
    let mut pattern = format!("pict_{name}");
    while groups.contains(&pattern) {
        pattern.insert(0, '_');
    }
    pattern
}

/// A textured group's recovered map, how it is read, and the lobe's specularity that
/// RADIANCE's plastic takes out of it.
struct Picture<'a> {
    map: &'a Image,
    wrap: Wrap,
    specularity: f64,
}

/// Where a textured group's (u, v) come from in its RADIANCE `.cal`.
enum Placement<'a> {
    /// An affine function of the hit point (Px, Py, Pz), as on obj2rad's polygons; the
    /// function is in the frame the scene was moved to, whose origin is the second field
    /// in the scene's own coordinates (`OwnedScene::origin`), where RADIANCE evaluates it.
    Affine(&'a texture::UvAffine, [f64; 3]),
    /// The obj2mesh mesh's own texture coordinates (Lu, Lv): a curved group.
    Mesh,
}

/// The RADIANCE picture and mapping of a textured group: `textures/<group>.hdr` holds the
/// map over (1 - s) (RADIANCE's plastic multiplies the picture by its colour and (1 - s));
/// `textures/<group>.cal` turns the hit point (or on a mesh, the mesh's (Lu, Lv)) into
/// the OBJ (u, v) and remaps it so that
/// RADIANCE, which interpolates between the first and last texel over [0, 1], samples the
/// texel centres where the OBJ convention puts them (as in the references' tex_*.cal).
fn add_radiance_picture(
    set: &mut OutputSet,
    out: &Path,
    name: &str,
    Picture {
        map,
        wrap,
        specularity,
    }: Picture,
    placement: Placement,
) -> Result<(), Error> {
    let scale = 1.0 / (1.0 - specularity as f32).max(1e-3);
    let picture = Image {
        width: map.width,
        height: map.height,
        pixels: map.pixels.iter().map(|p| p.map(|c| c * scale)).collect(),
    };
    let hdr = out.join(TEXTURES_DIR).join(format!("{name}.hdr"));
    set.add(&hdr, &images::hdr_bytes(&hdr, &picture)?)?;
    let uv = match placement {
        Placement::Affine(affine, origin) => {
            let (o, gu, gv) = (affine.origin, affine.grad_u, affine.grad_v);
            // The point the function is expanded about, back in the scene's own
            // coordinates (in 64 bits: a scene 300 km from its origin is moved to its
            // centre, and f32 there is 3 cm coarse); written as before at origin 0.
            let at = |c: f32, shift: f64| {
                if shift == 0.0 {
                    c.to_string()
                } else {
                    (f64::from(c) + shift).to_string()
                }
            };
            let (ox, oy, oz) = (at(o.x, origin[0]), at(o.y, origin[1]), at(o.z, origin[2]));
            format!(
                "{{ relume: OBJ (u, v) of group {name} as an affine function of the hit point }}\n\
                 N = {n};\n\
                 obj_u = {u0} + (Px-({ox}))*({gux}) + (Py-({oy}))*({guy}) + (Pz-({oz}))*({guz});\n\
                 obj_v = {v0} + (Px-({ox}))*({gvx}) + (Py-({oy}))*({gvy}) + (Pz-({oz}))*({gvz});\n",
                n = map.width,
                u0 = affine.uv0[0],
                v0 = affine.uv0[1],
                gux = gu.x,
                guy = gu.y,
                guz = gu.z,
                gvx = gv.x,
                gvy = gv.y,
                gvz = gv.z,
            )
        }
        Placement::Mesh => format!(
            "{{ relume: OBJ (u, v) of group {name}, read on its obj2mesh mesh (meshes/{name}.rtm)\n\
               as the mesh's local coordinates Lu, Lv }}\n\
             N = {n};\n\
             obj_u = Lu;\n\
             obj_v = Lv;\n",
            n = map.width,
        ),
    };
    let cal = match wrap {
        Wrap::Clamp => format!(
            "{uv}\
             {{ held to the picture, as relume's lookup clamps at the border: RADIANCE\n\
                extrapolates a picture past its edge, then tapers it to black }}\n\
             unit(x) = if(x, if(x - 1, 1, x), 0);\n\
             pic_u = unit((obj_u*N - .5)/(N - 1));\n\
             pic_v = unit((obj_v*N - .5)/(N - 1));\n"
        ),
        Wrap::Repeat => format!(
            "{uv}\
             {{ tiled: each whole step of (u, v) repeats the picture. RADIANCE holds a\n\
                picture to its edge texels, where relume's lookup blends the last texel\n\
                into the first: the two differ within half a texel of each seam }}\n\
             unit(x) = if(x, if(x - 1, 1, x), 0);\n\
             repeat(x) = x - floor(x);\n\
             pic_u = unit((repeat(obj_u)*N - .5)/(N - 1));\n\
             pic_v = unit((repeat(obj_v)*N - .5)/(N - 1));\n"
        ),
    };
    set.add(
        &out.join(TEXTURES_DIR).join(format!("{name}.cal")),
        cal.as_bytes(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene_file::GroupKind;

    /// A scene of `groups` (name, objects) and `lights` (objects), its own paths made up.
    fn scene(groups: &[(&str, &[&str])], lights: &[&str]) -> SceneDesc {
        SceneDesc {
            path: "scene.toml".into(),
            name: "s".into(),
            geometry: vec!["g.obj".into()],
            hide: Vec::new(),
            views: Vec::new(),
            lights: (lights.iter())
                .map(|o| crate::scene_file::LightDesc {
                    object: o.to_string(),
                    radiance: [1.0; 3],
                })
                .collect(),
            groups: (groups.iter().enumerate())
                .map(|(i, (name, objects))| crate::scene_file::GroupDesc {
                    name: name.to_string(),
                    kind: GroupKind::Plastic,
                    objects: objects.iter().map(|o| o.to_string()).collect(),
                    line: i + 1,
                })
                .collect(),
        }
    }

    /// An object named by OBJ `file` (`o` or `g` statements).
    fn object(name: &str, named_by_g: bool) -> ObjObject {
        ObjObject {
            name: name.into(),
            file: "g.obj".into(),
            triangles: Vec::new(),
            uvs: None,
            named_by_g,
            line: 7,
            crossing_faces: Vec::new(),
        }
    }

    /// A light's primitive takes no group's name, nor another light's, and holds only
    /// what a RADIANCE identifier may (`ceiling lamp` gave `light_ceiling lamp`).
    #[test]
    fn a_light_primitive_is_an_identifier_of_its_own() {
        let desc = scene(
            &[("light_lamp", &["shade"])],
            &["lamp", "bulb", "ceiling lamp", "ceiling_lamp"],
        );
        let groups = ["light_lamp".to_string()];
        assert_eq!(
            light_names(&desc, &groups),
            [
                "_light_lamp",
                "light_bulb",
                "light_ceiling_lamp",
                "_light_ceiling_lamp"
            ]
        );
    }

    /// materials.map's rules as RADIANCE's obj2rad names objects: `Group` where the file
    /// names them by `g`, and no rule (a comment) for a name of two words or a quote, which
    /// obj2rad cannot match (`(Object "box"red")` was a malformed rule); such an object is
    /// warned of, naming its file and line.
    #[test]
    fn materials_map_names_objects_as_obj2rad_does() {
        let desc = scene(
            &[
                ("wall", &["north", "south"]),
                ("box", &["box red", "box\"blue"]),
            ],
            &["lamp"],
        );
        let objects = [
            object("north", false),
            object("south", true),
            object("box red", false),
            object("box\"blue", false),
            object("lamp", true),
        ];
        let (names, warnings) = Obj2radNames::new(&desc, &objects);
        let groups = ["wall".to_string(), "box".to_string()];
        let map = obj2rad_map(&desc, &groups, &[], &names);
        let rules: Vec<&str> = map.lines().skip(2).collect();
        assert_eq!(
            rules,
            [
                "wall (Object \"north\") ;",
                "wall (Group \"south\") ;",
                "# box: object \"box red\" has no rule: obj2rad names objects by one word",
                "# box: object \"box\\\"blue\" has no rule: obj2rad names objects by one word",
                "light_lamp (Group \"lamp\") ;",
            ]
        );
        assert_eq!(warnings.len(), 2, "{warnings:?}");
        assert!(
            warnings[0].starts_with(
                "object 'box red' (g.obj, line 7): RADIANCE's obj2rad names an object by one word"
            ),
            "{warnings:?}"
        );
    }

    /// A group named `pict_X` took the name of X's picture pattern, and RADIANCE, binding
    /// a name to its last definition, rendered X's surfaces invisible.
    #[test]
    fn a_picture_pattern_takes_no_groups_name() {
        let groups = ["wall", "pict_wall", "_pict_wall"].map(String::from);
        assert_eq!(pattern_name("wall", &groups), "__pict_wall");
        assert_eq!(pattern_name("pict_wall", &groups), "pict_pict_wall");
        assert_eq!(pattern_name("floor", &groups[..1]), "pict_floor");
    }
}

#[cfg(test)]
mod curved_tests {
    use glam::Vec3;

    use super::super::WRITTEN;
    use super::*;
    use crate::assemble::{self, MaterialSource};
    use crate::recover::model::MapLobe;

    /// A flat picture `label` (u, v along y, z in the plane x = 0), a half-cylinder
    /// `wrap` whose u runs round it (no affine function of the point), a plain floor and a
    /// lamp; `label` and `wrap` textured.
    fn scene(dir: &Path) -> Recovery {
        scene_shifted(dir, 0.0)
    }

    /// [`scene`] moved `shift` along x, OBJ and view alike.
    fn scene_shifted(dir: &Path, shift: f64) -> Recovery {
        let mut obj = String::from(
            "o label\nv 0 0.2 0.2\nv 0 0.8 0.2\nv 0 0.8 0.8\nv 0 0.2 0.8\n\
             vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nf 1/1 2/2 3/3 4/4\n\
             o floor\nv 0 0 0\nv 2 0 0\nv 2 2 0\nv 0 2 0\nf 5 6 7 8\n\
             o lamp\nv 0.5 0.5 1.9\nv 1.5 0.5 1.9\nv 1.5 1.5 1.9\nf 9 11 10\n\
             o wrap\n",
        );
        let segments = 6;
        for i in 0..=segments {
            let a = std::f64::consts::PI * i as f64 / segments as f64;
            let (x, y) = (1.2 + 0.3 * libm::cos(a), 1.0 + 0.3 * libm::sin(a));
            let u = i as f64 / segments as f64;
            obj.push_str(&format!(
                "v {x} {y} 0.1\nv {x} {y} 0.6\nvt {u} 0\nvt {u} 1\n"
            ));
        }
        for i in 0..segments {
            // Vertices 12 + 2i (bottom) and 13 + 2i (top); vt 5 + 2i and 6 + 2i.
            let (b, t, nb, nt) = (12 + 2 * i, 13 + 2 * i, 14 + 2 * i, 15 + 2 * i);
            let (tb, tt, tnb, tnt) = (5 + 2 * i, 6 + 2 * i, 7 + 2 * i, 8 + 2 * i);
            obj.push_str(&format!("f {b}/{tb} {nb}/{tnb} {nt}/{tnt} {t}/{tt}\n"));
        }
        let obj: String = obj
            .lines()
            .map(|l| match l.strip_prefix("v ") {
                Some(xyz) => {
                    let (x, yz) = xyz.split_once(' ').unwrap();
                    format!("v {} {yz}\n", x.parse::<f64>().unwrap() + shift)
                }
                None => format!("{l}\n"),
            })
            .collect();
        std::fs::write(dir.join("geo.obj"), obj).unwrap();
        let toml = r#"format = 1
name = "curved"
geometry = ["geo.obj"]
hide = []

[[view]]
name = "front"
image = "views/front.exr"
position = [1.5, 1.0, 1.0]
direction = [-1.0, 0.0, 0.0]
up = [0.0, 0.0, 1.0]
fov_deg = [90.0, 90.0]
size = [8, 8]
exposure = 1.0

[[light]]
object = "lamp"
radiance = [5.0, 5.0, 5.0]

[[group]]
name = "label"
kind = "plastic"
objects = ["label"]

[[group]]
name = "floor"
kind = "plastic"
objects = ["floor"]

[[group]]
name = "wrap"
kind = "plastic"
objects = ["wrap"]
"#
        .replace("position = [1.5,", &format!("position = [{},", 1.5 + shift));
        std::fs::write(dir.join("scene.toml"), toml).unwrap();
        let owned =
            assemble::load_and_assemble(&dir.join("scene.toml"), MaterialSource::GeometryOnly)
                .unwrap();
        let map = |base: f32| texture::RecoveredMap {
            wrap: Wrap::Clamp,
            side: 4,
            texels: (0..16)
                .map(|i| Vec3::new(base, 0.05 * i as f32, 0.5 - 0.02 * i as f32))
                .collect(),
        };
        Recovery {
            views: Vec::new(),
            real: Vec::new(),
            pure: Vec::new(),
            models: vec![
                GroupModel::Textured {
                    map: 0,
                    lobe: MapLobe::None,
                },
                GroupModel::Diffuse {
                    color: [0.5, 0.4, 0.3],
                },
                GroupModel::Textured {
                    map: 1,
                    lobe: MapLobe::Isotropic {
                        specularity: 0.05,
                        roughness: 0.1,
                    },
                },
            ],
            owned,
            maps: vec![map(0.2), map(0.7)],
            pool: std::sync::Arc::new(crate::parallel::thread_pool(Some(1)).unwrap()),
            seed: 1,
            terms_memo: Default::default(),
            started: std::time::Instant::now(),
        }
    }

    /// Asserts that the label's .cal gives the OBJ's (u, v) at three of its corners (at x
    /// = `shift`), evaluating its `obj_u` and `obj_v` lines, and clamps as relume's lookup.
    fn assert_label_cal_places_the_map(cal: &str, shift: f64) {
        // obj_u = u0 + (Px-(ox))*(gx) + (Py-(oy))*(gy) + (Pz-(oz))*(gz), evaluated at p.
        let evaluate = |name: &str, p: [f64; 3]| {
            let line = cal.lines().find(|l| l.starts_with(name)).unwrap();
            let rhs = line.split_once(" = ").unwrap().1.trim_end_matches(';');
            let numbers: Vec<f64> = rhs
                .split(|c: char| "()*+ ".contains(c) || c.is_ascii_alphabetic())
                .filter(|t| !t.is_empty() && *t != "-")
                .map(|t| t.parse().unwrap())
                .collect();
            let [u0, ox, gx, oy, gy, oz, gz] = numbers[..] else {
                panic!("{rhs}: {numbers:?}")
            };
            u0 + (p[0] - ox) * gx + (p[1] - oy) * gy + (p[2] - oz) * gz
        };
        for (p, uv) in [
            ([shift, 0.2, 0.2], [0.0, 0.0]),
            ([shift, 0.8, 0.2], [1.0, 0.0]),
            ([shift, 0.8, 0.8], [1.0, 1.0]),
        ] {
            let got = [evaluate("obj_u", p), evaluate("obj_v", p)];
            assert!(
                (got[0] - uv[0]).abs() < 1e-4 && (got[1] - uv[1]).abs() < 1e-4,
                "{p:?}: {got:?} against {uv:?}\n{cal}"
            );
        }
        assert!(
            cal.contains("N = 4;\n")
                && cal.contains("unit(x) = if(x, if(x - 1, 1, x), 0);\n")
                && cal.contains("pic_u = unit((obj_u*N - .5)/(N - 1));\n")
                && cal.contains("pic_v = unit((obj_v*N - .5)/(N - 1));\n"),
            "{cal}"
        );
    }

    /// A flat picture's .cal gives the OBJ's (u, v) at the OBJ's points in a scene far
    /// from its origin too: the scene is moved to its centre to be rendered, and the
    /// .cal's affine function was written in that moved frame, where RADIANCE evaluates
    /// it in the OBJ's own.
    #[test]
    fn a_flat_pictures_cal_is_in_the_objs_coordinates_far_from_the_origin() {
        let shift = 300_000.0;
        let dir = tempfile::tempdir().unwrap();
        let rec = scene_shifted(dir.path(), shift);
        assert!(rec.owned.origin[0] != 0.0, "the scene is moved");
        let out = dir.path().join("out");
        let mut set = OutputSet::keeping(Vec::new());
        add_maps_and_radiance(&mut set, &out, &rec, &Obj2radNames::default()).unwrap();
        set.commit().unwrap();
        let cal = std::fs::read_to_string(out.join("textures/label.cal")).unwrap();
        assert_label_cal_places_the_map(&cal, shift);
    }

    /// A tiled map's .cal repeats the picture at each whole step of (u, v), as relume's
    /// lookup does; a clamped map's beside it is held to the picture as before.
    #[test]
    fn a_tiled_maps_cal_repeats_the_picture() {
        let dir = tempfile::tempdir().unwrap();
        let mut rec = scene(dir.path());
        rec.maps[0].wrap = Wrap::Repeat;
        let out = dir.path().join("out");
        let mut set = OutputSet::keeping(Vec::new());
        add_maps_and_radiance(&mut set, &out, &rec, &Obj2radNames::default()).unwrap();
        set.commit().unwrap();
        let read = |f: &str| std::fs::read_to_string(out.join(f)).unwrap();
        let label = read("textures/label.cal");
        assert!(
            label.contains("repeat(x) = x - floor(x);\n")
                && label.contains("pic_u = unit((repeat(obj_u)*N - .5)/(N - 1));\n")
                && label.contains("pic_v = unit((repeat(obj_v)*N - .5)/(N - 1));\n"),
            "{label}"
        );
        let wrap = read("textures/wrap.cal");
        assert!(
            wrap.contains("pic_u = unit((obj_u*N - .5)/(N - 1));") && !wrap.contains("repeat"),
            "{wrap}"
        );
    }

    /// A curved textured group lost its whole map in RADIANCE (written as its mean
    /// colour): its (u, v) are no affine function of the hit point, which is all a
    /// picture on obj2rad's polygons can be given. It is now written as an obj2mesh mesh
    /// of its faces with their (u, v), read as Lu, Lv, its objects left out of obj2rad's
    /// polygons; a flat picture is written as before, and an earlier run's mesh, which
    /// holds that run's materials, is removed.
    #[test]
    fn a_curved_textured_group_keeps_its_map_as_an_obj2mesh_mesh() {
        let dir = tempfile::tempdir().unwrap();
        let rec = scene(dir.path());
        let out = dir.path().join("out");
        std::fs::create_dir_all(out.join("meshes")).unwrap();
        for stale in ["meshes/wrap.rtm", "meshes/old.obj", "meshes/old.rtm"] {
            std::fs::write(out.join(stale), b"an earlier run's").unwrap();
        }
        let mut set = OutputSet::keeping(Vec::new());
        add_maps_and_radiance(&mut set, &out, &rec, &Obj2radNames::default()).unwrap();
        for (folder, extensions) in WRITTEN {
            set.remove_unwritten_on_commit(&out.join(folder), extensions);
        }
        set.commit().unwrap();
        let read = |f: &str| std::fs::read_to_string(out.join(f)).unwrap();
        let rad = read("materials.rad");

        // The flat picture: its colorpict on the hit point, as before.
        assert!(
            rad.contains(
                "\nvoid colorpict pict_label\n7 red green blue textures/label.hdr textures/label.cal pic_u pic_v\n0\n0\n\npict_label plastic label\n0\n0\n5 1 1 1 0 0\n"
            ),
            "{rad}"
        );
        assert!(!rad.contains("label.mesh") && !out.join("meshes/label.obj").exists());
        assert!(texture::uv_affine(&rec, 0).is_some(), "the label is flat");
        assert_label_cal_places_the_map(&read("textures/label.cal"), 0.0);

        // The curved group: its map (not its mean), on the mesh's (Lu, Lv).
        assert!(texture::uv_affine(&rec, 2).is_none(), "the wrap is curved");
        assert!(!rad.contains("map's mean colour"), "{rad}");
        assert!(
            rad.contains("#   obj2mesh -a materials.rad meshes/wrap.obj meshes/wrap.rtm\n")
                && rad.contains(
                    "\nvoid colorpict pict_wrap\n7 red green blue textures/wrap.hdr textures/wrap.cal pic_u pic_v\n0\n0\n\npict_wrap plastic wrap\n"
                )
                && rad.contains("\nvoid mesh wrap.mesh\n1 meshes/wrap.rtm\n0\n0\n"),
            "{rad}"
        );
        let cal = read("textures/wrap.cal");
        assert!(
            cal.contains("N = 4;\nobj_u = Lu;\nobj_v = Lv;\n")
                && cal.contains("pic_u = unit((obj_u*N - .5)/(N - 1));")
                && !cal.contains("Px"),
            "{cal}"
        );
        assert!(out.join("textures/wrap.hdr").is_file() && out.join("textures/wrap.exr").is_file());
        // Its faces, with their (u, v) as the OBJ gave them, all under its material.
        let mesh = read("meshes/wrap.obj");
        let lines = |prefix: &str| mesh.lines().filter(|l| l.starts_with(prefix)).count();
        assert_eq!(
            (lines("f "), lines("v "), lines("vt ")),
            (12, 36, 36),
            "{mesh}"
        );
        assert_eq!(lines("usemtl "), 1);
        assert!(
            mesh.contains("usemtl wrap\n") && mesh.contains("\nvt 0.5 1\n"),
            "{mesh}"
        );
        assert!(mesh.contains("\nv 0.9 1 0.1\n"), "{mesh}");

        // obj2rad leaves the curved group's faces to the mesh (a `void` rule it skips).
        let map = read("materials.map");
        assert!(
            map.contains("label (Object \"label\") ;\nfloor (Object \"floor\") ;\n")
                && map.contains("\nvoid (Object \"wrap\") ;\n")
                && !map.contains("wrap (Object"),
            "{map}"
        );
        // An earlier run's meshes are gone (the .rtm held that run's materials).
        for stale in ["meshes/wrap.rtm", "meshes/old.obj", "meshes/old.rtm"] {
            assert!(!out.join(stale).exists(), "{stale}");
        }
    }
}
