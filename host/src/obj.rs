//! Wavefront OBJ geometry (scene-format.md): named objects of faces, fan-triangulated
//! unless concave (`polygon`).
//!
//! Reading is two passes. Our own pass over the text checks every statement and reports
//! `file:line` errors (tobj gives no positions), decides the object names, and writes a
//! normalised copy (`o`, `v`, `vt` and `f` with absolute indices, nothing else); tobj then
//! loads that copy. Triangles keep the file's order: objects in file order, faces in file
//! order, polygons fanned from their first vertex, matching the "one global triangle index in
//! file order" of the ray benchmarks.
//!
//! Rules (format 1):
//! - An object is an `o` name; in a file without `o` lines, a `g` name (and `g` lines are
//!   ignored in a file that has `o` lines). A name is the rest of its line, trimmed.
//! - A face before any `o`/`g` is an error ("face outside any object"): the scene must be able
//!   to name every face. An object name used twice in one file is an error (names must be
//!   unique; see `scene_file::check_objects` across files). An object without faces is left out.
//! - `v`: 3 finite numbers (6 with a vertex colour, ignored; 4 with the spec's weight, only
//!   its default 1: readers differ on dividing by any other); `vt`: 1 to 3 finite numbers
//!   (v 0 when left out, as the spec says; w ignored);
//!   `f`: at least 3 vertices `v`, `v/vt`, `v//vn` or `v/vt/vn`, indices 1-based or negative
//!   (relative), referring to vertices, texture coordinates and normals already read; a face
//!   uses texture coordinates on all of its vertices or on none.
//! - A control character other than whitespace (a NUL) is an error: not a separator.
//! - A line ending in `\` goes on in the next (errors name the line a statement starts
//!   on); a comment line does not.
//! - Ignored: comments, `vn` (flat shading), `s`, `mtllib`, `usemtl` (materials come from
//!   materials.toml), `l` and `p` (lines and points have no area), `vp` (free-form
//!   geometry's parameter points, checked to be numbers). Any other statement
//!   (free-form curves, typos) is an error.
//! - An object's `uvs` are present only when all of its faces have texture coordinates.

use std::borrow::Cow;
use std::collections::HashMap;
use std::io::Cursor;
use std::path::{Path, PathBuf};

use crate::error::Error;
use crate::polygon::Cut;

/// One named object of an OBJ file.
#[derive(Clone, Debug, PartialEq)]
pub struct ObjObject {
    pub name: String,
    /// The OBJ file it comes from.
    pub file: PathBuf,
    /// Triangles in file order, counter-clockwise as in the file, in 64 bits: rounded to
    /// 32 only once the scene is moved near its origin (`assemble::far_scene_centre`).
    pub triangles: Vec<[[f64; 3]; 3]>,
    /// Texture coordinates per triangle corner, when every face has them.
    pub uvs: Option<Vec<[[f32; 2]; 3]>>,
    /// Named by a `g` statement (its file has no `o`): RADIANCE's obj2rad knows it as a
    /// group, not an object (materials.map).
    pub named_by_g: bool,
    /// The line that names it.
    pub line: usize,
    /// The lines of its faces that cross themselves: no triangles cover such a polygon,
    /// so it is fanned from its first corner, as tobj does ([`crossing_face_warnings`]).
    pub crossing_faces: Vec<usize>,
}

/// What the checking pass learns about one object.
struct ObjectInfo {
    name: String,
    line: usize,
    n_triangles: usize,
    all_uv: bool,
    /// The lines of its faces that cross themselves (fanned, as tobj does).
    crossing_faces: Vec<usize>,
}

/// The checking pass: per-object facts and the normalised text for tobj.
struct Checked {
    objects: Vec<ObjectInfo>,
    text: String,
    /// The file names its objects by `g` (it has no `o`).
    named_by_g: bool,
}

/// A warning per OBJ file whose faces (of `objects` that are shown) cross themselves,
/// naming the first and how many: fanned, such a face covers what its author may not have
/// meant, and RADIANCE renders its polygon otherwise.
pub fn crossing_face_warnings<'a>(objects: impl IntoIterator<Item = &'a ObjObject>) -> Vec<String> {
    let mut per_file: Vec<(&Path, &str, usize, usize)> = Vec::new();
    for o in objects {
        let Some(&first) = o.crossing_faces.first() else {
            continue;
        };
        match per_file.iter_mut().find(|f| f.0 == o.file.as_path()) {
            Some(f) => {
                f.3 += o.crossing_faces.len();
                if first < f.2 {
                    (f.1, f.2) = (&o.name, first);
                }
            }
            None => per_file.push((&o.file, &o.name, first, o.crossing_faces.len())),
        }
    }
    per_file
        .into_iter()
        .map(|(file, name, line, count)| {
            let others = match count {
                1 => String::new(),
                n => format!(" ({n} faces of this file cross themselves; this is the first)"),
            };
            format!(
                "{}:{line}: a face of object '{name}' crosses itself{others}: it was cut into triangles fanned from its first corner, which cover parts twice or outside it; split it into faces that do not cross",
                file.display()
            )
        })
        .collect()
}

/// Reads one OBJ file into its objects.
pub fn load_obj(path: &Path) -> Result<Vec<ObjObject>, Error> {
    let text = crate::fsutil::read_text(path)?;
    let checked = check_text(path, &text)?;
    // tobj parses the checked copy, so the file's own text need not outlive the check:
    // held through tobj's parse, the peak of a large scene's memory, a 66-MB mesh of
    // 600,000 triangles peaked at 320 MB, and 255 MB without it.
    drop(text);
    let with_faces: Vec<&ObjectInfo> = checked
        .objects
        .iter()
        .filter(|o| o.n_triangles > 0)
        .collect();
    if with_faces.is_empty() {
        return Err(Error::input(path, "the file has no faces"));
    }
    let options = tobj::LoadOptions {
        single_index: false,
        triangulate: true,
        ignore_points: true,
        ignore_lines: true,
    };
    let mut reader = Cursor::new(checked.text.as_bytes());
    let (models, _) = tobj::load_obj_buf(&mut reader, &options, |_| {
        Err(tobj::LoadError::OpenFileFailed)
    })
    .map_err(|e| {
        Error::input(
            path,
            format!("OBJ loader (tobj) failed after checking: {e}"),
        )
    })?;
    // tobj gives a trailing object without faces as an empty model (one in the middle of
    // the file it drops): objects without faces are no part of the geometry either way.
    let models: Vec<tobj::Model> = models
        .into_iter()
        .filter(|m| !m.mesh.indices.is_empty())
        .collect();
    let disagree = |what: String| {
        Error::input(
            path,
            format!("internal: the OBJ loader disagrees with the checker: {what}"),
        )
    };
    if models.len() != with_faces.len() {
        return Err(disagree(format!(
            "{} objects, expected {}",
            models.len(),
            with_faces.len()
        )));
    }
    let mut out = Vec::with_capacity(models.len());
    for (model, info) in models.iter().zip(with_faces) {
        let m = &model.mesh;
        if model.name != info.name || m.indices.len() != 3 * info.n_triangles {
            return Err(disagree(format!(
                "object '{}' (line {}): {} corners, expected {}",
                info.name,
                info.line,
                m.indices.len(),
                3 * info.n_triangles
            )));
        }
        let position = |i: u32| -> Option<[f64; 3]> {
            let i = i as usize * 3;
            Some([
                *m.positions.get(i)?,
                *m.positions.get(i + 1)?,
                *m.positions.get(i + 2)?,
            ])
        };
        let texcoord = |i: u32| -> Option<[f32; 2]> {
            let i = i as usize * 2;
            Some([*m.texcoords.get(i)? as f32, *m.texcoords.get(i + 1)? as f32])
        };
        let mut triangles = Vec::with_capacity(info.n_triangles);
        for c in m.indices.chunks_exact(3) {
            match (position(c[0]), position(c[1]), position(c[2])) {
                (Some(a), Some(b), Some(c)) => triangles.push([a, b, c]),
                _ => {
                    return Err(disagree(format!(
                        "object '{}': vertex index out of range",
                        info.name
                    )))
                }
            }
        }
        let uvs = if info.all_uv {
            if m.texcoord_indices.len() != m.indices.len() {
                return Err(disagree(format!(
                    "object '{}': texture coordinates missing",
                    info.name
                )));
            }
            let mut uvs = Vec::with_capacity(info.n_triangles);
            for c in m.texcoord_indices.chunks_exact(3) {
                match (texcoord(c[0]), texcoord(c[1]), texcoord(c[2])) {
                    (Some(a), Some(b), Some(c)) => uvs.push([a, b, c]),
                    _ => {
                        return Err(disagree(format!(
                            "object '{}': vt index out of range",
                            info.name
                        )))
                    }
                }
            }
            Some(uvs)
        } else {
            None
        };
        out.push(ObjObject {
            name: info.name.clone(),
            file: path.to_path_buf(),
            triangles,
            uvs,
            named_by_g: checked.named_by_g,
            line: info.line,
            crossing_faces: info.crossing_faces.clone(),
        });
    }
    Ok(out)
}

/// The line (1-based) where object `name` starts in an OBJ file, for error messages.
pub fn object_line(path: &Path, name: &str) -> Option<usize> {
    let text = crate::fsutil::read_text(path).ok()?;
    let statements = statements(&text);
    let has_o = statements.iter().any(|(_, l)| keyword(l) == Some("o"));
    let naming = if has_o { "o" } else { "g" };
    statements
        .iter()
        .find(|(_, l)| keyword(l) == Some(naming) && rest_after_keyword(l) == name)
        .map(|(line, _)| *line)
}

/// The line of a `g name` statement in an OBJ file that names its objects by `o`, where
/// `g` makes a group within an object and no object: for the message about a scene that
/// names it as an object (Blender writes `o Cube` and then `g Cube_Material`).
pub fn group_line_under_o(path: &Path, name: &str) -> Option<usize> {
    let text = crate::fsutil::read_text(path).ok()?;
    let statements = statements(&text);
    if !statements.iter().any(|(_, l)| keyword(l) == Some("o")) {
        return None;
    }
    statements
        .iter()
        .find(|(_, l)| keyword(l) == Some("g") && rest_after_keyword(l) == name)
        .map(|(line, _)| *line)
}

/// The file's statements, each with the line (1-based) it starts on: a line that ends in
/// `\` goes on in the next one (the OBJ format's line continuation, which some exporters
/// use to wrap long faces).
fn statements(text: &str) -> Vec<(usize, Cow<'_, str>)> {
    let mut out = Vec::new();
    let mut pending: Option<(usize, String)> = None;
    // Lines that end in CR alone (classic Mac OS) read as one line, and the file as one
    // with no faces.
    let cr_only = text.contains('\r') && !text.contains('\n');
    let lines: Box<dyn Iterator<Item = &str>> = match cr_only {
        true => Box::new(text.split('\r')),
        false => Box::new(text.lines()),
    };
    for (i, line) in lines.enumerate() {
        // A comment ends at its line, whatever it ends in (a Windows path's `\`).
        let comment = pending.is_none() && line.trim_start().starts_with('#');
        let (body, continues) = match line.trim_end().strip_suffix('\\') {
            Some(body) if !comment => (body.trim_end(), true),
            _ => (line, false),
        };
        let statement = match pending.take() {
            Some((first, mut joined)) => {
                // The break reads as one space, however the lines were indented.
                joined.push(' ');
                joined.push_str(body.trim_start());
                (first, Cow::Owned(joined))
            }
            None => (i + 1, Cow::Borrowed(body)),
        };
        if continues {
            pending = Some((statement.0, statement.1.into_owned()));
        } else {
            out.push(statement);
        }
    }
    out.extend(pending.map(|(line, joined)| (line, Cow::Owned(joined))));
    out
}

fn keyword(line: &str) -> Option<&str> {
    line.split_whitespace().next()
}

/// The text after the first token, trimmed (an `o`/`g` name may contain spaces).
fn rest_after_keyword(line: &str) -> &str {
    let t = line.trim_start();
    let end = t.find(char::is_whitespace).unwrap_or(t.len());
    t[end..].trim()
}

fn check_text(path: &Path, text: &str) -> Result<Checked, Error> {
    let statements = statements(text);
    let has_o = statements.iter().any(|(_, l)| keyword(l) == Some("o"));
    let naming = if has_o { "o" } else { "g" };
    let mut objects: Vec<ObjectInfo> = Vec::new();
    // Each name's line, to find one given twice without comparing it with every other.
    let mut named_at: HashMap<&str, usize> = HashMap::new();
    let mut out = String::with_capacity(text.len());
    let (mut n_v, mut n_vt, mut n_vn) = (0usize, 0usize, 0usize);
    // The vertices' positions, for the triangles of a concave face (`polygon`).
    let mut positions: Vec<[f64; 3]> = Vec::new();
    for (line_no, raw_line) in &statements {
        let (line_no, raw_line) = (*line_no, raw_line.as_ref());
        let err = |msg: String| Error::at_line(path, line_no, msg);
        // A NUL or another control character is no separator: `f 5 7\0 6` read as a
        // face of two vertices, and `o la\0mp` as an object the scene could not find.
        if let Some(c) = raw_line
            .chars()
            .find(|c| c.is_control() && !c.is_whitespace())
        {
            return Err(err(format!(
                "control character U+{:04X} in the line: not OBJ text",
                c as u32
            )));
        }
        let mut tokens = raw_line.split_whitespace();
        let Some(key) = tokens.next() else { continue };
        let args: Vec<&str> = tokens.collect();
        match key {
            k if k.starts_with('#') => {}
            "v" => {
                let xs = numbers(&args, "v", &err)?;
                match xs.len() {
                    3 | 6 => {}
                    // The spec's weight, for rational curves: a polygon's corner takes none,
                    // and some readers divide by it, so only its default is unambiguous.
                    4 if xs[3] == 1.0 => {}
                    4 => {
                        return Err(err(format!(
                            "`v` has a weight w = {} (the 4th number): relume reads polygons, whose corners take no weight, and readers differ on whether to divide by it; write the position itself (x/w y/w z/w if that is what it means), or w = 1",
                            args[3]
                        )))
                    }
                    n => {
                        return Err(err(format!(
                            "`v` needs 3 numbers (x y z, 4 with a weight of 1, or 6 with a vertex colour), found {n}"
                        )))
                    }
                }
                out.push_str(&format!("v {} {} {}\n", args[0], args[1], args[2]));
                positions.push([0, 1, 2].map(|k| args[k].parse::<f64>().unwrap_or(0.0)));
                n_v += 1;
            }
            "vt" => {
                one_to_three_numbers(&args, "vt", "u, v and w, v and w 0 if left out", &err)?;
                // The spec's default v is 0 (a 1D texture); w has no place in a 2D map.
                let v = args.get(1).copied().unwrap_or("0");
                out.push_str(&format!("vt {} {v}\n", args[0]));
                n_vt += 1;
            }
            "f" => {
                let Some(current) = objects.last_mut() else {
                    return Err(err(format!(
                        "face outside any object: add a `{naming} <name>` line before it"
                    )));
                };
                if args.len() < 3 {
                    return Err(err(format!(
                        "a face needs at least 3 vertices, found {}",
                        args.len()
                    )));
                }
                let mut with_uv = 0;
                let mut corners = Vec::with_capacity(args.len());
                let mut tokens = Vec::with_capacity(args.len());
                for a in &args {
                    let (v, vt) = face_vertex(a, n_v, n_vt, n_vn)
                        .map_err(|m| err(format!("face vertex '{a}': {m}")))?;
                    corners.push(positions[v - 1]);
                    match vt {
                        Some(t) => {
                            with_uv += 1;
                            tokens.push(format!("{v}/{t}"));
                        }
                        None => tokens.push(format!("{v}")),
                    }
                }
                if with_uv != 0 && with_uv != args.len() {
                    return Err(err(
                        "the face gives texture coordinates for some vertices but not all"
                            .to_string(),
                    ));
                }
                current.all_uv &= with_uv == args.len();
                // A convex face stays one line, which tobj fans as before; a concave one
                // becomes its ears. One that crosses itself is fanned, and told of.
                match crate::polygon::cut(&corners) {
                    Cut::Ears(ears) => {
                        // Fewer than a fan's where a corner was given twice.
                        current.n_triangles += ears.len();
                        for [a, b, c] in ears {
                            out.push_str(&format!("f {} {} {}\n", tokens[a], tokens[b], tokens[c]));
                        }
                    }
                    cut => {
                        current.n_triangles += args.len() - 2;
                        if cut == Cut::CrossesItself {
                            current.crossing_faces.push(line_no);
                        }
                        out.push_str(&format!("f {}\n", tokens.join(" ")));
                    }
                }
            }
            "o" | "g" if key == naming => {
                let name = rest_after_keyword(raw_line);
                if name.is_empty() {
                    return Err(err(format!("`{key}` without a name")));
                }
                // A name may hold spaces, so `o floor # comment` would silently name an
                // object "floor # comment"; OBJ has no trailing comments (as on `v` lines).
                if name.contains('#') {
                    return Err(err(format!(
                        "object name '{name}' contains '#': OBJ has no comments after a statement; put the comment on a line of its own"
                    )));
                }
                if let Some(first) = named_at.insert(name, line_no) {
                    return Err(err(format!(
                        "object '{name}' appears twice in the file (first at line {first}): names must be unique"
                    )));
                }
                objects.push(ObjectInfo {
                    name: name.to_string(),
                    line: line_no,
                    n_triangles: 0,
                    all_uv: true,
                    crossing_faces: Vec::new(),
                });
                out.push_str(&format!("o {name}\n"));
            }
            "vn" => n_vn += 1,
            // Free-form geometry's parameter-space points: harmless alone, and whatever
            // would use them (`curv`, `surf`, ...) is refused below.
            "vp" => {
                one_to_three_numbers(&args, "vp", "u v w", &err)?;
            }
            "g" | "s" | "mtllib" | "usemtl" | "l" | "p" => {}
            other => return Err(err(format!("unknown OBJ statement '{other}'"))),
        }
    }
    Ok(Checked {
        objects,
        text: out,
        named_by_g: !has_o,
    })
}

/// [`numbers`], and 1 to 3 of them, as `vt` and `vp` take (`form` names them).
fn one_to_three_numbers(
    args: &[&str],
    key: &str,
    form: &str,
    err: &dyn Fn(String) -> Error,
) -> Result<(), Error> {
    let n = numbers(args, key, err)?.len();
    if !(1..=3).contains(&n) {
        return Err(err(format!(
            "`{key}` needs 1 to 3 numbers ({form}), found {n}"
        )));
    }
    Ok(())
}

/// Parses all arguments as finite numbers.
fn numbers(args: &[&str], key: &str, err: &dyn Fn(String) -> Error) -> Result<Vec<f32>, Error> {
    let mut xs = Vec::with_capacity(args.len());
    for a in args {
        match a.parse::<f32>() {
            Ok(x) if x.is_finite() => xs.push(x),
            Ok(x) => return Err(err(format!("`{key}` has a non-finite number '{a}' ({x})"))),
            Err(_) => return Err(err(format!("`{key}`: '{a}' is not a number"))),
        }
    }
    Ok(xs)
}

/// One `v[/vt[/vn]]` reference, as absolute 1-based indices (the normal is checked to
/// refer to a `vn` read so far, and then not used: shading is flat).
fn face_vertex(
    token: &str,
    n_v: usize,
    n_vt: usize,
    n_vn: usize,
) -> Result<(usize, Option<usize>), String> {
    let parts: Vec<&str> = token.split('/').collect();
    if parts.len() > 3 {
        return Err("expected v, v/vt, v//vn or v/vt/vn".into());
    }
    let v = resolve_index(parts[0], n_v, "vertex")?;
    let vt = match parts.get(1) {
        None | Some(&"") => None,
        Some(t) => Some(resolve_index(t, n_vt, "texture coordinate")?),
    };
    if let Some(n) = parts.get(2) {
        resolve_index(n, n_vn, "normal")?;
    }
    Ok((v, vt))
}

fn resolve_index(s: &str, n: usize, what: &str) -> Result<usize, String> {
    let i: i64 = s
        .parse()
        .map_err(|_| format!("{what} index '{s}' is not an integer"))?;
    let n_i = n as i64;
    let abs = if i > 0 { i } else { n_i + i + 1 };
    if i == 0 || abs < 1 || abs > n_i {
        return Err(format!(
            "{what} index {i} is out of range ({n} defined so far)"
        ));
    }
    Ok(abs as usize)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write(text: &str) -> (tempfile::TempDir, PathBuf) {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("geo.obj");
        std::fs::write(&path, text).unwrap();
        (dir, path)
    }

    fn load(text: &str) -> Vec<ObjObject> {
        let (_dir, path) = write(text);
        load_obj(&path).unwrap_or_else(|e| panic!("{e}"))
    }

    /// Loading must fail naming geo.obj, `line` and every one of `what`.
    fn bad(text: &str, line: usize, what: &[&str]) {
        let (_dir, path) = write(text);
        let e = load_obj(&path)
            .expect_err("the OBJ should be refused")
            .to_string();
        eprintln!("{e}");
        assert!(
            e.contains(&format!("geo.obj:{line}:")),
            "expected geo.obj:{line} in: {e}"
        );
        for w in what {
            assert!(e.contains(w), "expected {w:?} in: {e}");
        }
    }

    const QUAD: &str = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n";

    #[test]
    fn objects_and_fan_triangles_in_file_order() {
        let objs = load(&format!(
            "# c\no a\n{QUAD}f 1 2 3 4\no b\nv 0 0 1\nf 1 2 5\nf 5 2 3\n"
        ));
        assert_eq!(objs.len(), 2);
        assert_eq!(objs[0].name, "a");
        assert!(objs[0].file.ends_with("geo.obj"));
        let v = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 1.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
        ];
        assert_eq!(
            objs[0].triangles,
            vec![[v[0], v[1], v[2]], [v[0], v[2], v[3]]]
        );
        assert_eq!(
            objs[1].triangles,
            vec![[v[0], v[1], v[4]], [v[4], v[1], v[2]]]
        );
        assert_eq!(objs[0].uvs, None);
    }

    /// A statement wrapped with `\` reads as the one line it stands for; an error in it
    /// names the line it starts on, later lines keep their numbers, and a comment that
    /// ends in `\` (a Windows folder) does not swallow the statement after it.
    #[test]
    fn a_line_ending_in_a_backslash_goes_on_in_the_next() {
        // What a file holds, less where it is.
        let geometry = |objs: Vec<ObjObject>| -> Vec<_> {
            objs.into_iter()
                .map(|o| (o.name, o.triangles, o.uvs))
                .collect()
        };
        let load = |text: &str| geometry(load(text));
        let plain = load(&format!("o a\n{QUAD}f 1 2 3 4\no b\nf 1 2 3\n"));
        let wrapped = load(
            "o a\nv 0 0 0\nv 1 \\\n 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 \\\n3 \\\n 4\no b\nf 1 2 3\n",
        );
        assert_eq!(wrapped, plain);
        let commented = load(&format!(
            "# from C:\\models\\\no a\n{QUAD}f 1 2 3 4\no b\nf 1 2 3\n"
        ));
        assert_eq!(commented, plain);
        bad(
            &format!("o a\n{QUAD}f 1 2 \\\n 3 9\n"),
            6,
            &["vertex index 9 is out of range"],
        );
        bad(
            &format!("o a\nv 0 \\\n0 0\n{QUAD}f 1 2 3\nbogus\n"),
            9,
            &["unknown OBJ statement 'bogus'"],
        );
        let (_dir, path) = write(&format!("o a\n{QUAD}f 1 2 \\\n 3\no b \\\nc\nf 1 2 3\n"));
        assert_eq!(object_line(&path, "b c"), Some(8));
    }

    /// An object without faces is no object of the geometry, wherever it stands (tobj
    /// drops one in the middle and gave one at the end as an empty model, which the
    /// loader then refused as an internal disagreement).
    #[test]
    fn objects_without_faces_are_left_out_anywhere_in_the_file() {
        for (text, expected) in [
            (format!("o empty\no a\n{QUAD}f 1 2 3\n"), vec!["a"]),
            (
                format!("o a\n{QUAD}f 1 2 3\no empty\nv 0 0 2\no b\nf 1 2 4\n"),
                vec!["a", "b"],
            ),
            (
                format!("o a\n{QUAD}f 1 2 3\no b\nf 1 2 4\no empty\n"),
                vec!["a", "b"],
            ),
        ] {
            let names: Vec<String> = load(&text).into_iter().map(|o| o.name).collect();
            assert_eq!(names, expected, "from {text:?}");
        }
    }

    /// A file whose lines end in CR alone was one line, with no faces.
    #[test]
    fn lines_that_end_in_cr_alone_are_lines() {
        let text = format!("o a\n{QUAD}f 1 2 3\n").replace('\n', "\r");
        let objs = load(&text);
        assert_eq!(objs.len(), 1);
        assert_eq!(objs[0].triangles.len(), 1);
        let (_dir, path) = write(&text);
        assert_eq!(object_line(&path, "a"), Some(1));
    }

    /// An L-shaped face: tobj's fan from its first corner, (2, 0), put a triangle over
    /// its notch; its ears keep the polygon's area (3) and winding, with each corner's
    /// texture coordinates.
    #[test]
    fn a_concave_polygon_is_cut_into_ears_with_its_texture_coordinates() {
        let objs = load(
            "o l\nv 2 0 0\nv 2 1 0\nv 1 1 0\nv 1 2 0\nv 0 2 0\nv 0 0 0\n\
             vt 1 0\nvt 1 0.5\nvt 0.5 0.5\nvt 0.5 1\nvt 0 1\nvt 0 0\n\
             f 1/1 2/2 3/3 4/4 5/5 6/6\n",
        );
        let o = &objs[0];
        assert_eq!(o.triangles.len(), 4);
        let mut area = 0.0;
        for (t, uv) in o.triangles.iter().zip(o.uvs.as_ref().unwrap()) {
            let twice = (t[1][0] - t[0][0]) * (t[2][1] - t[0][1])
                - (t[1][1] - t[0][1]) * (t[2][0] - t[0][0]);
            assert!(twice > 0.0, "{t:?} turned over");
            area += twice / 2.0;
            // Each corner keeps its own coordinates (here half its position).
            for (p, q) in t.iter().zip(uv) {
                assert_eq!([p[0] as f32 / 2.0, p[1] as f32 / 2.0], *q);
            }
            // No triangle reaches into the notch (x > 1 and y > 1).
            let p = [1.2, 1.2];
            let side = |a: [f64; 3], b: [f64; 3]| {
                (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0]) > 0.0
            };
            let holds = side(t[0], t[1]) && side(t[1], t[2]) && side(t[2], t[0]);
            assert!(!holds, "{t:?} covers the notch");
        }
        assert_eq!(area, 3.0);
    }

    /// A bow tie is fanned, as tobj fans it, and its line kept for the warning, which names
    /// the file, the first such line and how many; an L given one corner twice (once an ulp
    /// off) loses only that corner's triangle.
    #[test]
    fn a_face_that_crosses_itself_is_fanned_and_told() {
        let objs = load(
            "o bow\nv 0 0 0\nv 2 1 0\nv 2 0 0\nv 0 3 0\nf 1 2 3 4\n\
             o l\nv 2 0 0\nv 2 1 0\nv 1 1 0\nv 1.0000000000000002 1 0\nv 1 2 0\nv 0 2 0\nv 0 0 0\n\
             f 5 6 7 8 9 10 11\nf 4 3 2 1\n",
        );
        assert_eq!(objs[0].crossing_faces, vec![6]);
        assert_eq!(objs[0].triangles.len(), 2);
        assert_eq!(objs[1].crossing_faces, vec![16]);
        assert_eq!(objs[1].triangles.len(), 4 + 2);
        let warnings = crossing_face_warnings(&objs);
        assert_eq!(warnings.len(), 1, "{warnings:?}");
        assert!(
            warnings[0].contains(".obj:6: a face of object 'bow' crosses itself (2 faces of this file cross themselves; this is the first)"),
            "{warnings:?}"
        );
        assert!(crossing_face_warnings(&objs[1..])[0].contains(":16: a face of object 'l'"));
    }

    #[test]
    fn convex_polygons_are_fanned_from_their_first_vertex() {
        let objs = load("o p\nv 0 0 0\nv 1 0 0\nv 2 1 0\nv 1 2 0\nv 0 1 0\nf 1 2 3 4 5\n");
        let t: Vec<[f64; 3]> = objs[0]
            .triangles
            .iter()
            .map(|t| [t[0][0], t[1][0], t[2][0]])
            .collect();
        assert_eq!(t, vec![[0.0, 1.0, 2.0], [0.0, 2.0, 1.0], [0.0, 1.0, 0.0]]);
    }

    #[test]
    fn negative_indices_are_relative() {
        let objs = load(&format!("o a\n{QUAD}f -4 -3 -2\n"));
        assert_eq!(
            objs[0].triangles,
            vec![[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0]]]
        );
    }

    #[test]
    fn g_names_objects_only_in_files_without_o() {
        let objs = load(&format!("g a\n{QUAD}f 1 2 3\ng b\nf 1 3 4\n"));
        assert_eq!(
            objs.iter().map(|o| o.name.as_str()).collect::<Vec<_>>(),
            ["a", "b"]
        );
        let objs = load(&format!("o a\ng part1\n{QUAD}f 1 2 3\ng part2\nf 1 3 4\n"));
        assert_eq!(objs.len(), 1);
        assert_eq!(objs[0].triangles.len(), 2);
    }

    #[test]
    fn names_may_contain_spaces() {
        let objs = load(&format!("o  big lamp  \n{QUAD}f 1 2 3\n"));
        assert_eq!(objs[0].name, "big lamp");
    }

    #[test]
    fn texture_coordinates_when_every_face_has_them() {
        let text = format!(
            "o t\n{QUAD}vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1 0\nvn 0 0 1\nf 1/1/1 2/2/1 3/3/1 4/4/1\n\
                            o u\nf 1/1 2/2 3/3\nf 1//1 3//1 4//1\n"
        );
        let objs = load(&text);
        let uv = objs[0].uvs.as_ref().unwrap();
        assert_eq!(
            uv,
            &vec![
                [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]],
                [[0.0, 0.0], [1.0, 1.0], [0.0, 1.0]]
            ]
        );
        assert_eq!(objs[1].uvs, None);
        assert_eq!(objs[1].triangles.len(), 2);
    }

    #[test]
    fn ignored_statements() {
        let objs = load(&format!(
            "mtllib x.mtl\no a\nusemtl red\ns 1\n{QUAD}vn 0 0 1\nf 1 2 3\nusemtl blue\nf 1 3 4\nl 1 2 3\np 1\n"
        ));
        assert_eq!(objs.len(), 1);
        assert_eq!(objs[0].triangles.len(), 2);
    }

    #[test]
    fn objects_without_faces_are_left_out() {
        let objs = load(&format!("o empty\no a\n{QUAD}f 1 2 3\n"));
        assert_eq!(objs.len(), 1);
        assert_eq!(objs[0].name, "a");
    }

    #[test]
    fn bad_vertices() {
        bad("o a\nv 1 2\n", 2, &["`v` needs 3 numbers", "found 2"]);
        bad("o a\nv 1 2 3 0.5\n", 2, &["weight w = 0.5", "x/w y/w z/w"]);
        bad("o a\nv 1 2 3 4 5\n", 2, &["`v` needs 3 numbers", "found 5"]);
        bad("o a\nv 1 x 3\n", 2, &["'x' is not a number"]);
        bad("o a\nv 1 nan 3\n", 2, &["non-finite number 'nan'"]);
        bad("o a\nv 1 inf 3\n", 2, &["non-finite"]);
        bad("o a\nv 1 2 1e39\n", 2, &["non-finite"]);
    }

    #[test]
    fn bad_texture_coordinates() {
        bad("o a\nvt\n", 2, &["`vt` needs 1 to 3 numbers", "found 0"]);
        bad(
            "o a\nvt 0 0 0 0\n",
            2,
            &["`vt` needs 1 to 3 numbers", "found 4"],
        );
        bad("o a\nvt 0.5 y\n", 2, &["'y' is not a number"]);
        bad("o a\nvt 0.5 nan\n", 2, &["non-finite"]);
    }

    #[test]
    fn bad_faces() {
        bad(
            &format!("o a\n{QUAD}f 1 2\n"),
            6,
            &["at least 3 vertices, found 2"],
        );
        bad(
            &format!("o a\n{QUAD}f 1 2 5\n"),
            6,
            &["vertex index 5 is out of range (4 defined so far"],
        );
        bad(
            &format!("o a\n{QUAD}f 1 2 -5\n"),
            6,
            &["vertex index -5 is out of range"],
        );
        bad(
            &format!("o a\n{QUAD}f 0 1 2\n"),
            6,
            &["vertex index 0 is out of range"],
        );
        bad(
            &format!("o a\n{QUAD}f 1 2 x\n"),
            6,
            &["face vertex 'x'", "not an integer"],
        );
        bad(
            &format!("o a\n{QUAD}f 1/1 2/1 3/1\n"),
            6,
            &["texture coordinate index 1 is out of range (0"],
        );
        bad(
            &format!("o a\n{QUAD}vt 0 0\nf 1/1 2/1 3\n"),
            7,
            &["some vertices but not all"],
        );
        bad(
            &format!("o a\n{QUAD}f 1//z 2 3\n"),
            6,
            &["normal index 'z'"],
        );
        // A normal must exist though shading is flat: the file is wrong where it points.
        bad(
            &format!("o a\n{QUAD}f 1//1 2//1 3//1\n"),
            6,
            &["normal index 1 is out of range (0 defined so far)"],
        );
        bad(
            &format!("o a\n{QUAD}f 1 2 3\x006\n"),
            6,
            &["control character U+0000"],
        );
        bad(
            &format!("o a\x00b\n{QUAD}f 1 2 3\n"),
            1,
            &["control character U+0000"],
        );
        bad(
            &format!("o a\n{QUAD}f 1/1/1/1 2 3\n"),
            6,
            &["expected v, v/vt"],
        );
        // A vertex defined after the face is not yet available.
        bad(
            "o a\nv 0 0 0\nv 1 0 0\nf 1 2 3\nv 1 1 0\n",
            4,
            &["vertex index 3 is out of range"],
        );
    }

    #[test]
    fn a_face_outside_any_object_is_an_error() {
        bad(
            &format!("{QUAD}f 1 2 3\no a\nf 1 3 4\n"),
            5,
            &["face outside any object", "add a `o <name>` line"],
        );
        bad(
            &format!("{QUAD}f 1 2 3\n"),
            5,
            &["face outside any object", "`g <name>`"],
        );
    }

    #[test]
    fn unknown_statements_are_errors() {
        bad("o a\ncurv 0 1 1 2\n", 2, &["unknown OBJ statement 'curv'"]);
        bad("o a\nvp 0.5 x\n", 2, &["`vp`: 'x' is not a number"]);
    }

    /// The spec's optional numbers: a `v` weight of 1, a `vt` without v (0) or with w, and
    /// `vp` lines read as the plain file does.
    #[test]
    fn optional_numbers_of_the_spec_are_read() {
        let plain =
            load("o a\nv 0 0 0\nv 1 0 0\nv 1 1 0\nvt 0.25 0\nvt 1 0\nvt 1 0\nf 1/1 2/2 3/3\n");
        let spec = load(
            "o a\nv 0 0 0 1\nv 1 0 0 1.0\nv 1 1 0\nvp 0.5\nvp 0.5 0.5 1\nvt 0.25\nvt 1 0 0.7\nvt 1\nf 1/1 2/2 3/3\n",
        );
        assert_eq!(spec.len(), 1);
        assert_eq!(spec[0].triangles, plain[0].triangles);
        assert_eq!(spec[0].uvs, plain[0].uvs);
        assert_eq!(spec[0].uvs.as_ref().unwrap()[0][0], [0.25, 0.0]);
    }

    #[test]
    fn duplicate_and_empty_object_names_are_errors() {
        bad(
            &format!("o a\n{QUAD}f 1 2 3\no b\nf 1 3 4\no a\nf 2 3 4\n"),
            9,
            &["object 'a' appears twice", "first at line 1"],
        );
        bad(
            &format!("g a\n{QUAD}f 1 2 3\ng a\nf 1 3 4\n"),
            7,
            &["object 'a' appears twice"],
        );
        bad("o\n", 1, &["`o` without a name"]);
    }

    #[test]
    fn a_comment_after_an_object_name_is_an_error_not_part_of_the_name() {
        bad(
            &format!("o floor # the floor\n{QUAD}f 1 2 3\n"),
            1,
            &[
                "object name 'floor # the floor' contains '#'",
                "a line of its own",
            ],
        );
        bad(
            &format!("g a#1\n{QUAD}f 1 2 3\n"),
            1,
            &["'a#1' contains '#'"],
        );
    }

    #[test]
    fn a_file_without_faces_is_an_error() {
        let (_dir, path) = write(&format!("o a\n{QUAD}"));
        let e = load_obj(&path).unwrap_err().to_string();
        assert!(e.contains("geo.obj") && e.contains("no faces"), "{e}");
    }

    #[test]
    fn a_missing_file_is_an_io_error_naming_it() {
        let dir = tempfile::tempdir().unwrap();
        let e = load_obj(&dir.path().join("absent.obj")).unwrap_err();
        assert!(matches!(e, Error::Io { .. }));
        assert!(e.to_string().contains("absent.obj"), "{e}");
    }

    #[test]
    fn object_line_finds_the_naming_line() {
        let (_dir, path) = write(&format!("o a\n{QUAD}f 1 2 3\no b c\nf 1 3 4\n"));
        assert_eq!(object_line(&path, "b c"), Some(7));
        assert_eq!(object_line(&path, "zz"), None);
    }

    /// Triangles of an OBJ by the most naive reading of the text (every `o` starts an object,
    /// faces fanned from the first vertex), to compare the loader with.
    fn naive(text: &str) -> Vec<(String, [[f64; 3]; 3])> {
        let mut v: Vec<[f64; 3]> = Vec::new();
        let mut name = String::new();
        let mut out = Vec::new();
        for line in text.lines() {
            let t: Vec<&str> = line.split_whitespace().collect();
            match t.first() {
                Some(&"o") => name = t[1].to_string(),
                Some(&"v") => v.push([
                    t[1].parse().unwrap(),
                    t[2].parse().unwrap(),
                    t[3].parse().unwrap(),
                ]),
                Some(&"f") => {
                    let idx: Vec<usize> = t[1..]
                        .iter()
                        .map(|s| s.split('/').next().unwrap().parse::<usize>().unwrap() - 1)
                        .collect();
                    for k in 2..idx.len() {
                        out.push((name.clone(), [v[idx[0]], v[idx[k - 1]], v[idx[k]]]));
                    }
                }
                _ => {}
            }
        }
        out
    }

    #[test]
    fn bench_geometry_loads_in_file_order() {
        let Some(bench) = crate::scene_file::tests::bench() else {
            return;
        };
        for (scene, n_objects, n_triangles) in [
            ("box-diffuse", 9, 38),
            ("living-room", 26, 2374),
            ("glossy", 14, 2162),
            ("textured", 15, 736),
        ] {
            let path = bench.join(scene).join("geometry.obj");
            let objs = load_obj(&path).unwrap_or_else(|e| panic!("{e}"));
            assert_eq!(objs.len(), n_objects, "{scene}");
            let flat: Vec<(String, [[f64; 3]; 3])> = objs
                .iter()
                .flat_map(|o| o.triangles.iter().map(|t| (o.name.clone(), *t)))
                .collect();
            assert_eq!(flat.len(), n_triangles, "{scene}");
            assert_eq!(
                flat,
                naive(&std::fs::read_to_string(&path).unwrap()),
                "{scene}"
            );
        }
    }

    #[test]
    fn textured_bench_pictures_have_uvs() {
        let Some(bench) = crate::scene_file::tests::bench() else {
            return;
        };
        let objs = load_obj(&bench.join("textured/geometry.obj")).unwrap();
        let with_uv: Vec<&str> = objs
            .iter()
            .filter(|o| o.uvs.is_some())
            .map(|o| o.name.as_str())
            .collect();
        assert!(!with_uv.is_empty());
        for o in objs.iter().filter(|o| o.uvs.is_some()) {
            assert_eq!(o.uvs.as_ref().unwrap().len(), o.triangles.len());
        }
    }
}
