//! Reading TOML with positions, shared by scene.toml and materials.toml: byte spans to
//! 1-based lines and columns, numbers checked finite and within f32, fixed-length vectors.

use std::ops::Range;
use std::path::{Path, PathBuf};

use serde::de::DeserializeOwned;
use serde::Deserialize;
use toml::Spanned;

use crate::error::{Error, Location};

/// The text of one TOML file and its path.
pub struct TomlFile {
    pub path: PathBuf,
    pub text: String,
}

#[derive(Deserialize)]
struct FormatOnly {
    format: Option<Spanned<toml::Value>>,
}

/// The longest name of a group or a view: it names output files (`<view>.exr`,
/// `textures/<group>.exr`, and their temp files `.<name>.tmp-<pid>`), and a file name
/// may be 255 bytes long.
pub const MAX_NAME_LEN: usize = 200;

/// The name of a table header line, `[name]` (not a list's `[[name]]`).
fn table_header(line: &str) -> Option<&str> {
    let inner = line.strip_prefix('[').filter(|t| !t.starts_with('['))?;
    Some(inner.split(']').next()?.trim())
}

/// The name of a list entry's header line, `[[name]]`.
fn list_header(line: &str) -> Option<&str> {
    Some(line.strip_prefix("[[")?.split("]]").next()?.trim())
}

impl TomlFile {
    /// Reads the file (an I/O error names it).
    pub fn read(path: &Path) -> Result<TomlFile, Error> {
        let text = crate::fsutil::read_text(path)?;
        Ok(TomlFile {
            path: path.to_path_buf(),
            text,
        })
    }

    /// 1-based line and column (in characters) of a byte offset.
    pub fn line_col(&self, offset: usize) -> (usize, usize) {
        let offset = offset.min(self.text.len());
        let before = self.text.get(..offset).unwrap_or(&self.text);
        let line = before.matches('\n').count() + 1;
        let start = before.rfind('\n').map_or(0, |i| i + 1);
        (line, before[start..].chars().count() + 1)
    }

    pub fn line_of(&self, offset: usize) -> usize {
        self.line_col(offset).0
    }

    /// An input error at the start of `span`.
    pub fn at(&self, span: Range<usize>, message: impl Into<String>) -> Error {
        let (line, column) = self.line_col(span.start);
        Error::Input {
            file: self.path.clone(),
            location: Some(Location::Line {
                line,
                column: Some(column),
            }),
            message: message.into(),
        }
    }

    /// Parses the whole file (syntax, types, missing and unknown keys).
    pub fn parse<T: DeserializeOwned>(&self) -> Result<T, Error> {
        toml::from_str(&self.text).map_err(|e| self.de_error(&e))
    }

    fn de_error(&self, e: &toml::de::Error) -> Error {
        let message = e
            .message()
            .replace("missing field", "missing key")
            .replace("unknown field", "unknown key")
            .replace("expected one of", "expected one of the keys")
            .replace("expected f64", "expected a number")
            .replace("expected i64", "expected an integer");
        // An integer past TOML's 64 bits: "invalid type: integer `<20 digits>` as i128,
        // expected an integer" said the type was wrong.
        let message = match message.strip_suffix("` as i128, expected an integer") {
            Some(head) => format!(
                "{}` is out of range: TOML's integers are 64-bit",
                head.replacen("invalid type: integer `", "integer `", 1)
            ),
            None => message,
        };
        match e.span() {
            Some(span) => self.with_hint(message, span),
            None => Error::input(&self.path, message),
        }
    }

    /// The toml crate's error at `span`, with what it means where a table header
    /// `[view]` was written for a list's `[[view]]`: a "duplicate key" at the second
    /// `[view]` or at a `[[view]]` after it (then said at the `[view]`), an "invalid
    /// type: map" at a lone one. A bare "duplicate key" is a key given twice.
    fn with_hint(&self, message: String, span: Range<usize>) -> Error {
        let line = self.line_of(span.start);
        let text = |line: usize| self.text.lines().nth(line - 1).unwrap_or("").trim();
        let list_entry = |name: &str| format!("each entry of a list is written [[{name}]]");
        let duplicate = message.contains("duplicate key");
        if let Some(name) = table_header(text(line)) {
            let hint = if duplicate {
                format!(": a table [{name}] may appear once; {}", list_entry(name))
            } else if message.contains("invalid type: map, expected a sequence") {
                format!(
                    ": [{name}] is a table, where a list is expected; {}",
                    list_entry(name)
                )
            } else {
                String::new()
            };
            return self.at(span, message + &hint);
        }
        if let Some(name) = list_header(text(line)).filter(|_| duplicate) {
            let earlier = self.text.lines().take(line - 1);
            if let Some(table) = earlier
                .map(str::trim)
                .position(|t| table_header(t) == Some(name))
                .map(|i| i + 1)
            {
                return Error::at_line(
                    &self.path,
                    table,
                    format!(
                        "[{name}] is a table, but [[{name}]] at line {line} makes a list; {}",
                        list_entry(name)
                    ),
                );
            }
        }
        // In an inline table (`light = [{object = "a", object = "b"}]`) the key given
        // twice is the one at the error, after the line's first `=`.
        let start = span.start.min(self.text.len());
        let line_start = self
            .text
            .get(..start)
            .and_then(|t| t.rfind('\n'))
            .map_or(0, |i| i + 1);
        let key_text = match self.text.get(line_start..start) {
            Some(before) if before.contains('=') => self.text[start..].lines().next().unwrap_or(""),
            _ => text(line),
        };
        let hint = match key_text.split('=').next().map(str::trim) {
            Some(key) if duplicate && !key.is_empty() => format!(": `{key}` is given twice"),
            _ => String::new(),
        };
        self.at(span, message + &hint)
    }

    /// `format` must be present and be the integer 1; checked before anything else so a
    /// newer file gets that error rather than one about its new keys.
    pub fn check_format(&self) -> Result<(), Error> {
        let f: FormatOnly = self.parse()?;
        match f.format {
            // A `format` line after a table header belongs to that table, in TOML:
            // the file had one, and the error named no line.
            None => match self.text.lines().position(|l| {
                l.split('=').next().map(str::trim) == Some("format") && l.contains('=')
            }) {
                Some(at) => Err(Error::at_line(
                    &self.path,
                    at + 1,
                    "`format` is given here, after a table header, so TOML reads it as a key of that table: put it at the top of the file, before the first [table] or [[list]] (this tool reads format = 1)",
                )),
                None => Err(Error::input(
                    &self.path,
                    "missing key `format` (this tool reads format = 1)",
                )),
            },
            Some(v) => match v.get_ref() {
                toml::Value::Integer(1) => Ok(()),
                other => Err(self.at(
                    v.span(),
                    format!("format {other} is not supported: this tool reads format = 1"),
                )),
            },
        }
    }

    /// A non-empty string.
    pub fn name(&self, s: &Spanned<String>, what: &str) -> Result<String, Error> {
        if s.get_ref().trim().is_empty() {
            return Err(self.at(s.span(), format!("{what} is empty")));
        }
        Ok(s.get_ref().clone())
    }

    /// A name that is also a file name and a RADIANCE identifier: ASCII letters,
    /// digits, `_`, `-` and `.`, not starting with `.` or `-`, and at most
    /// [`MAX_NAME_LEN`] long.
    pub fn identifier(&self, s: &Spanned<String>, what: &str) -> Result<String, Error> {
        let name = self.name(s, what)?;
        if name.len() > MAX_NAME_LEN {
            return Err(self.at(
                s.span(),
                format!(
                    "{what} is {} bytes long, more than MAX_NAME_LEN {MAX_NAME_LEN}: it names output files ('{}...')",
                    name.len(),
                    name.chars().take(40).collect::<String>().escape_debug()
                ),
            ));
        }
        if !name.chars().all(super::identifier_char) || name.starts_with(['.', '-']) {
            return Err(self.at(
                s.span(),
                format!(
                    "{what} {name:?} may hold only ASCII letters, digits, '_', '-' and '.', and must not start with '.' or '-': it names output files and RADIANCE primitives"
                ),
            ));
        }
        Ok(name)
    }

    /// [`TomlFile::identifier`] for a group, whose name is also its material's RADIANCE
    /// modifier in materials.rad: `void` there means no material at all, and a group so
    /// named rendered with none.
    pub fn group_identifier(&self, s: &Spanned<String>, what: &str) -> Result<String, Error> {
        let name = self.identifier(s, what)?;
        if name == "void" {
            return Err(self.at(
                s.span(),
                format!("{what} \"void\" is RADIANCE's word for no material: the group's material in materials.rad would be none"),
            ));
        }
        Ok(name)
    }

    /// A path relative to this file's folder (absolute paths stay as they are).
    pub fn resolve(&self, rel: &str) -> PathBuf {
        match self.path.parent() {
            Some(dir) => dir.join(rel),
            None => PathBuf::from(rel),
        }
    }

    /// A finite number that fits an f32.
    pub fn number(&self, v: &Spanned<f64>, what: &str) -> Result<f32, Error> {
        to_f32(*v.get_ref()).map_err(|m| self.at(v.span(), format!("`{what}` {m}")))
    }

    /// Exactly `N` finite numbers that fit an f32.
    pub fn vector<const N: usize>(
        &self,
        v: &Spanned<Vec<f64>>,
        what: &str,
    ) -> Result<[f32; N], Error> {
        self.numbers(v, what, to_f32)
    }

    /// Three finite numbers that give a direction, whose length does not matter: one
    /// whose squares would leave f32's range (`[1e-300, 0, 0]` read as zero, `[1e300,
    /// 0, 0]` as out of range), or the squares of its cross product with another (the
    /// core's view frame: `1e18` and `1e-18` left it), is first scaled by a power of
    /// two, exactly, to a largest component in [1, 2). Ordinary directions are kept as
    /// written.
    pub fn direction(&self, v: &Spanned<Vec<f64>>, what: &str) -> Result<[f32; 3], Error> {
        let d: [f64; 3] = self.numbers(v, what, |x| match x.is_finite() {
            true => Ok(x),
            false => Err(format!("must be a finite number, got {x}")),
        })?;
        let largest = d.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        if largest == 0.0 || (1e-6..=1e6).contains(&largest) {
            return Ok(d.map(|x| x as f32));
        }
        // 2^600 lifts an f64 subnormal to a normal number, whose exponent field is
        // then floor(log2); the scale 2^-exponent is built from its bits.
        let lift = if largest < f64::MIN_POSITIVE {
            f64::from_bits((1023 + 600) << 52)
        } else {
            1.0
        };
        let exponent = (((largest * lift).to_bits() >> 52) & 0x7ff) as i64 - 1023;
        // 2^-1023 is below the normal numbers, whose bits the scale is built from: a
        // largest of 2^1023 or more (up to f64::MAX) is halved first. It read as zero.
        let (halve, exponent) = match exponent > 1022 {
            true => (0.5, exponent - 1),
            false => (1.0, exponent),
        };
        let scale = f64::from_bits(((1023 - exponent) as u64) << 52);
        Ok(d.map(|x| (x * lift * halve * scale) as f32))
    }

    /// Exactly `N` finite numbers that fit an f32, kept in 64 bits.
    pub fn vector64<const N: usize>(
        &self,
        v: &Spanned<Vec<f64>>,
        what: &str,
    ) -> Result<[f64; N], Error> {
        self.numbers(v, what, |x| to_f32(x).map(|_| x))
    }

    fn numbers<T: Copy + Default, const N: usize>(
        &self,
        v: &Spanned<Vec<f64>>,
        what: &str,
        convert: fn(f64) -> Result<T, String>,
    ) -> Result<[T; N], Error> {
        let xs = v.get_ref();
        if xs.len() != N {
            return Err(self.at(
                v.span(),
                format!("`{what}` must have {N} numbers, found {}", xs.len()),
            ));
        }
        let mut out = [T::default(); N];
        for (o, &x) in out.iter_mut().zip(xs) {
            *o = convert(x).map_err(|m| self.at(v.span(), format!("`{what}` {m}")))?;
        }
        Ok(out)
    }
}

fn to_f32(x: f64) -> Result<f32, String> {
    if !x.is_finite() {
        return Err(format!("must be a finite number, got {x}"));
    }
    let y = x as f32;
    if !y.is_finite() {
        return Err(format!("is out of range for a 32-bit float: {x:e}"));
    }
    if y == 0.0 && x != 0.0 {
        return Err(format!(
            "is too small for a 32-bit float, which reads {x:e} as 0 (write 0 if 0 is meant)"
        ));
    }
    Ok(y)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene_file::load_scene;
    use crate::scene_file::tests::{bad, write};

    #[test]
    fn format_must_be_1() {
        bad(
            "format = 1",
            "format = 2",
            1,
            &["format 2 is not supported", "format = 1"],
        );
        bad("format = 1", "format = \"1\"", 1, &["is not supported"]);
        bad("format = 1", "format = 1.0", 1, &["is not supported"]);
        // A newer format is reported as such, not as its unknown keys.
        let (_dir, path) = write("format = 1", "format = 2\nshiny = true");
        let e = load_scene(&path).unwrap_err().to_string();
        assert!(e.contains("format 2"), "{e}");
    }

    #[test]
    fn missing_format_is_an_error() {
        let (_dir, path) = write("format = 1\n", "");
        let e = load_scene(&path).unwrap_err().to_string();
        assert!(
            e.contains("scene.toml") && e.contains("missing key `format`"),
            "{e}"
        );
    }

    /// `format = 1` after a table header is a key of that table in TOML: the file had
    /// one, and was told it had none, at no line.
    #[test]
    fn a_format_line_after_a_table_is_named_at_its_line() {
        let (_dir, path) = write("", "");
        let text = std::fs::read_to_string(&path).unwrap();
        let moved = format!("{}\nformat = 1\n", text.replacen("format = 1\n", "", 1));
        std::fs::write(&path, &moved).unwrap();
        let line = moved.lines().count();
        let e = load_scene(&path).unwrap_err().to_string();
        assert!(
            e.contains(&format!(
                "scene.toml:{line}: `format` is given here, after a table header"
            )),
            "{e}"
        );
    }

    #[test]
    fn syntax_errors_give_the_line() {
        bad("name = \"front\"", "name = \"front", 7, &["scene.toml:7:"]);
    }

    #[test]
    fn a_duplicate_key_says_which_and_a_table_written_twice_says_how_to_write_a_list() {
        bad(
            "format = 1",
            "format = 1\nformat = 1",
            2,
            &["duplicate key", "`format` is given twice"],
        );
        // Two views written [view] instead of [[view]].
        bad(
            "[[view]]",
            "[view]\nname = \"x\"\n\n[view]",
            9,
            &[
                "duplicate key",
                "a table [view] may appear once; each entry of a list is written [[view]]",
            ],
        );
        // A lone [view], and a [light] before a [[light]]: the toml crate's errors were
        // "invalid type: map, expected a sequence", and "duplicate key" at the [[light]].
        bad(
            "[[view]]",
            "[view]",
            6,
            &["[view] is a table, where a list is expected; each entry of a list is written [[view]]"],
        );
        bad(
            "[[light]]",
            "[light]\nobject = \"lamp\"\nradiance = [5.0, 5.0, 5.0]\n\n[[light]]",
            16,
            &["[light] is a table, but [[light]] at line 20 makes a list; each entry of a list is written [[light]]"],
        );
        // A key given twice in an inline table is that key, not the line's first
        // ("`light` is given twice").
        let e = bad(
            "hide = []",
            "hide = []\nlight = [{object = \"lamp\", object = \"x\", radiance = [5.0, 5.0, 5.0]}]",
            5,
            &["duplicate key", "`object` is given twice"],
        );
        assert!(!e.contains("`light`"), "{e}");
    }

    #[test]
    fn unknown_keys_are_errors() {
        bad(
            "hide = []",
            "hide = []\nnmae = \"x\"",
            5,
            &["unknown key `nmae`"],
        );
        bad(
            "exposure = 1.0",
            "exposure = 1.0\nexposre = 2.0",
            15,
            &["unknown key `exposre`"],
        );
        bad(
            "radiance = [5.0, 5.0, 5.0]",
            "radiance = [5.0, 5.0, 5.0]\ncolor = 1",
            19,
            &["unknown key `color`"],
        );
        bad(
            "objects = [\"quad\"]",
            "objects = [\"quad\"]\nobject = \"x\"",
            24,
            &["unknown key `object`"],
        );
    }

    #[test]
    fn missing_keys_are_errors() {
        bad("size = [8, 8]\n", "", 6, &["missing key `size`"]);
        bad(
            "position = [0.0, -2.0, 0.5]\n",
            "",
            6,
            &["missing key `position`"],
        );
        bad(
            "radiance = [5.0, 5.0, 5.0]\n",
            "",
            16,
            &["missing key `radiance`"],
        );
        bad("kind = \"plastic\"\n", "", 20, &["missing key `kind`"]);
        let (_dir, path) = write("name = \"t\"\n", "");
        let e = load_scene(&path).unwrap_err().to_string();
        assert!(
            e.contains("scene.toml") && e.contains("missing key `name`"),
            "{e}"
        );
        let (_dir, path) = write("geometry = [\"geo.obj\"]\n", "");
        let e = load_scene(&path).unwrap_err().to_string();
        assert!(e.contains("missing key `geometry`"), "{e}");
    }

    #[test]
    fn wrong_types_are_errors() {
        bad(
            "size = [8, 8]",
            "size = [8.5, 8]",
            13,
            &["expected an integer"],
        );
        bad(
            "exposure = 1.0",
            "exposure = \"bright\"",
            14,
            &["invalid type", "expected a number"],
        );
        bad(
            "objects = [\"quad\"]",
            "objects = \"quad\"",
            23,
            &["invalid type"],
        );
    }

    #[test]
    fn numbers_must_be_finite() {
        bad(
            "position = [0.0, -2.0, 0.5]",
            "position = [0.0, nan, 0.5]",
            9,
            &["`position`", "finite"],
        );
        bad(
            "direction = [0.0, 1.0, 0.0]",
            "direction = [0.0, inf, 0.0]",
            10,
            &["`direction`", "finite"],
        );
        bad(
            "exposure = 1.0",
            "exposure = -inf",
            14,
            &["`exposure`", "finite"],
        );
        bad(
            "radiance = [5.0, 5.0, 5.0]",
            "radiance = [5.0, nan, 5.0]",
            18,
            &["`radiance`", "finite"],
        );
        bad(
            "position = [0.0, -2.0, 0.5]",
            "position = [0.0, 1e40, 0.5]",
            9,
            &["out of range for a 32-bit float: 1e40"],
        );
        // Not silently 0: the number the file gives is named.
        bad(
            "radiance = [5.0, 5.0, 5.0]",
            "radiance = [5.0, 1e-50, 5.0]",
            18,
            &["`radiance` is too small for a 32-bit float, which reads 1e-50 as 0"],
        );
    }

    /// A direction's length does not matter: a tiny or huge one whose squares leave f32's
    /// range was read as zero or refused as out of range. Kept as written otherwise.
    #[test]
    fn tiny_and_huge_directions_are_directions() {
        let (_dir, path) = write(
            "direction = [0.0, 1.0, 0.0]\nup = [0.0, 0.0, 1.0]",
            "direction = [0.0, 1e-300, 0.0]\nup = [0.0, 0.0, 3e300]",
        );
        let in_unit_range = |v: [f32; 3], k: usize| {
            (1.0..2.0).contains(&v[k]) && (0..3).all(|i| i == k || v[i] == 0.0)
        };
        let desc = load_scene(&path).unwrap();
        assert!(
            in_unit_range(desc.views[0].direction, 1),
            "{:?}",
            desc.views[0]
        );
        assert!(in_unit_range(desc.views[0].up, 2), "{:?}", desc.views[0]);
        let (_dir, path) = write(
            "direction = [0.0, 1.0, 0.0]",
            "direction = [0.0, 5e-320, 0.0]",
        );
        let desc = load_scene(&path).unwrap();
        assert!(
            in_unit_range(desc.views[0].direction, 1),
            "{:?}",
            desc.views[0]
        );
        // From 2^1023 to f64::MAX, where the scale's bits once came out zero.
        for huge in ["1e308", "9e307", "1.7976931348623157e308"] {
            let (_dir, path) = write(
                "direction = [0.0, 1.0, 0.0]\nup = [0.0, 0.0, 1.0]",
                &format!("direction = [0.0, {huge}, 0.0]\nup = [0.0, 0.0, -{huge}]"),
            );
            let view = &load_scene(&path).unwrap().views[0];
            // f64::MAX over 2^1023 rounds to 2 in f32.
            let along = |v: [f32; 3], k: usize| {
                (1.0..=2.0).contains(&v[k]) && (0..3).all(|i| i == k || v[i] == 0.0)
            };
            assert!(along(view.direction, 1), "{huge}: {view:?}");
            assert!(along(view.up.map(|c| -c), 2), "{huge}: {view:?}");
        }
        let (_dir, path) = write("up = [0.0, 0.0, 1.0]", "up = [0.0, 0.0, 2.5]");
        assert_eq!(load_scene(&path).unwrap().views[0].up, [0.0, 0.0, 2.5]);
        bad(
            "direction = [0.0, 1.0, 0.0]",
            "direction = [0.0, 0.0, 0.0]",
            10,
            &["direction is zero"],
        );
    }

    /// Directions at the ends of the range kept as written: the core's frame squares
    /// their cross product, the fourth power of their size, which left f32's range (1e18)
    /// or fell below it (1e-18), and refused the view at no line as "up parallel to the
    /// direction".
    #[test]
    fn directions_kept_as_written_make_a_frame_in_the_core() {
        for size in ["1e18", "1e-18", "1e12", "1e-12", "1e6", "1e-6"] {
            let (_dir, path) = write(
                "direction = [0.0, 1.0, 0.0]\nup = [0.0, 0.0, 1.0]",
                &format!("direction = [0.0, {size}, 0.0]\nup = [0.0, 0.0, {size}]"),
            );
            let view = &load_scene(&path).unwrap().views[0];
            view.view()
                .unwrap_or_else(|e| panic!("{size}: {view:?}: {e}"));
        }
    }

    #[test]
    fn an_integer_past_64_bits_is_out_of_range() {
        bad(
            "size = [8, 8]",
            "size = [99999999999999999999, 8]",
            13,
            &["integer `99999999999999999999` is out of range: TOML's integers are 64-bit"],
        );
    }

    #[test]
    fn vectors_must_have_the_right_length() {
        bad(
            "position = [0.0, -2.0, 0.5]",
            "position = [0.0, -2.0]",
            9,
            &["`position` must have 3 numbers, found 2"],
        );
        bad(
            "up = [0.0, 0.0, 1.0]",
            "up = [0.0, 0.0, 1.0, 0.0]",
            11,
            &["`up` must have 3 numbers, found 4"],
        );
        bad(
            "fov_deg = [60.0, 60.0]",
            "fov_deg = [60.0]",
            12,
            &["`fov_deg` must have 2 numbers"],
        );
        bad(
            "size = [8, 8]",
            "size = [8, 8, 8]",
            13,
            &["size must have 2 integers"],
        );
        bad(
            "radiance = [5.0, 5.0, 5.0]",
            "radiance = [5.0]",
            18,
            &["`radiance` must have 3"],
        );
    }

    #[test]
    fn a_missing_scene_file_is_an_io_error_naming_it() {
        let dir = tempfile::tempdir().unwrap();
        let e = load_scene(&dir.path().join("absent.toml")).unwrap_err();
        assert!(matches!(e, Error::Io { .. }));
        assert!(e.to_string().contains("absent.toml"), "{e}");
    }

    #[test]
    fn line_and_column_of_offsets() {
        let f = TomlFile {
            path: "x.toml".into(),
            text: "ab\ncdé\nf".into(),
        };
        assert_eq!(f.line_col(0), (1, 1));
        assert_eq!(f.line_col(3), (2, 1));
        assert_eq!(f.line_col(7), (2, 4));
        assert_eq!(f.line_col(8), (3, 1));
        assert_eq!(f.line_col(1000), (3, 2));
    }
}
