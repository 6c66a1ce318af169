//! `relume panorama split` and `join`: an equirectangular panorama (a 360° capture, an
//! HDRI) split into the six cube faces that a scene's views are, each face pixel the mean radiance over its
//! square footprint as scene-format.md defines a pixel, with the `[[view]]` tables that
//! place them in the scene ([`split`](fn@split)); and the way back, a scene's views rendered from
//! one position (a relit room, say) joined into one equirectangular image, an environment
//! map for other tools ([`join`](fn@join)).
//!
//! The equirectangular convention, seen from inside as a 360° photo is: the image's centre
//! column looks along `forward`, columns run left to right as a viewer turning to the
//! right (towards `forward x up`), across the whole turn; rows run from straight up (the
//! top edge) to straight down. The faces are views of 90 x 90 degrees as `rpict -vtv`
//! renders them, so what this writes, recovery reads the right way round.
//!
//! The parts: `split` (a panorama into cube faces and their views) and `join` (views into
//! a panorama). Here: the [`Frame`] both take, and what both read of images and views.

use relume_core::geometry::View;
use relume_core::math::{self, Vec3};

use crate::error::Error;
use crate::images::Image;
use crate::obj::ObjObject;
use crate::scene_file::SceneDesc;

mod join;
mod split;

pub use join::{join, JoinArgs, Joined};
pub use split::{
    split, PanoramaArgs, PanoramaSummary, FACES_DIR, MIN_TEXELS_PER_PIXEL, VIEWS_TOML,
};

/// At most this many footprint samples per face pixel side.
const MAX_SAMPLES_PER_SIDE: u32 = 32;

/// The largest tilt of `--forward` off the horizon taken without a word: a vector typed
/// by hand, or read off a model, is seldom exactly level.
const MAX_FORWARD_TILT_DEG: f32 = 1.0;

/// The scene frame of the panorama: `forward` on the horizon, `right = forward x up`.
#[derive(Clone, Copy, Debug)]
pub struct Frame {
    pub forward: Vec3,
    pub right: Vec3,
    pub up: Vec3,
}

/// `v` (finite, non-zero) scaled by a power of two so that its largest component lies in
/// [1, 2): exactly, so a vector already there keeps its bits and its normalised value.
/// A tiny one (`1e-30,0,1e-30`) has a squared length below f32's range, and was called
/// zero or parallel.
fn to_unit_range(v: Vec3) -> Vec3 {
    // In f64 every f32 is normal: its exponent field is floor(log2), and 2^-exponent is
    // built from its bits.
    let largest = f64::from(v.abs().max_element());
    let exponent = ((largest.to_bits() >> 52) & 0x7ff) as i64 - 1023;
    let scale = f64::from_bits(((1023 - exponent) as u64) << 52);
    let exact = |c: f32| (f64::from(c) * scale) as f32;
    Vec3::new(exact(v.x), exact(v.y), exact(v.z))
}

impl Frame {
    /// `up` as given (normalised) and `forward` made perpendicular to it; a zero, non-finite
    /// or parallel pair is a usage error.
    pub fn new(forward: [f32; 3], up: [f32; 3]) -> Result<Frame, Error> {
        let (f, u) = (Vec3::from(forward), Vec3::from(up));
        if !(math::is_finite(f) && math::is_finite(u)) {
            return Err(Error::Usage(
                "--forward and --up must be finite vectors".into(),
            ));
        }
        for (v, name, given) in [(f, "--forward", forward), (u, "--up", up)] {
            if v == Vec3::ZERO {
                return Err(Error::Usage(format!("{name} {given:?} must not be zero")));
            }
        }
        let u = to_unit_range(u).normalize_or_zero();
        let f = to_unit_range(f);
        let f = (f - u * f.dot(u)).normalize_or_zero();
        if u == Vec3::ZERO || f == Vec3::ZERO {
            return Err(Error::Usage(format!(
                "--forward {forward:?} and --up {up:?} must not be parallel"
            )));
        }
        Ok(Frame {
            forward: f,
            right: f.cross(u),
            up: u,
        })
    }

    /// Where `--forward` (as given) leaves the horizon by more than
    /// `MAX_FORWARD_TILT_DEG`: the panorama's centre column is taken on the horizon, which
    /// a tilted `--forward` does not say (1,0,1 with up 0,0,1 gave a front face along x).
    pub fn tilt_warning(&self, forward: [f32; 3]) -> Option<String> {
        let given = to_unit_range(Vec3::from(forward)).normalize_or_zero();
        let tilt = given.dot(self.up).clamp(-1.0, 1.0).asin().to_degrees();
        (tilt.abs() > MAX_FORWARD_TILT_DEG).then(|| {
            let f = self.forward;
            format!(
                "--forward {forward:?} is {:.1} degrees off the horizon of --up: the panorama's centre column looks along the horizon, [{:.3}, {:.3}, {:.3}], which the front face's direction follows",
                tilt, f.x, f.y, f.z
            )
        })
    }

    /// The six faces: name, view direction, view up (the top of the face's image).
    pub fn faces(&self) -> [(&'static str, Vec3, Vec3); 6] {
        let (f, r, u) = (self.forward, self.right, self.up);
        [
            ("front", f, u),
            ("right", r, u),
            ("back", -f, u),
            ("left", -r, u),
            ("up", u, -f),
            ("down", -u, f),
        ]
    }

    /// The unit direction at `(u, v)` of the equirectangular image (the inverse of
    /// [`Frame::image_position`]).
    pub fn direction(&self, u: f32, v: f32) -> Vec3 {
        let azimuth = (u - 0.5) * 2.0 * math::PI;
        let elevation = (0.5 - v) * math::PI;
        (self.forward * math::cos(azimuth) + self.right * math::sin(azimuth)) * math::cos(elevation)
            + self.up * math::sin(elevation)
    }

    /// A unit direction's position in the equirectangular image, both in [0, 1]: `u` from
    /// the left edge, `v` from the top.
    pub fn image_position(&self, d: Vec3) -> (f32, f32) {
        let (x, y, z) = (d.dot(self.forward), d.dot(self.right), d.dot(self.up));
        let azimuth = math::atan2(y, x);
        let elevation = math::atan2(z, math::sqrt(x * x + y * y));
        (0.5 + azimuth / (2.0 * math::PI), 0.5 - elevation / math::PI)
    }
}

/// `image`'s radiance at pixel position `(x, y)` (pixel units, as [`View::ray`] takes
/// them): the texel there, the image taken as constant over each texel, as a camera's
/// pixel is its footprint's mean. Columns wrap around where `wrap` (an equirectangular
/// image's turn) and are clamped otherwise; rows are clamped (at a view's edge, at the
/// poles). Bilinear lookups were tried and dropped: they spread each texel over its
/// neighbours, and a light's texels, a hundred times the ceiling around them, into the
/// pure pixels beside it (the bundled scene's ceiling read 18% bright through a round trip).
fn texel_at(image: &Image, x: f32, y: f32, wrap: bool) -> Vec3 {
    let (w, h) = (image.width as i64, image.height as i64);
    let (i, j) = (math::floor(x) as i64, math::floor(y) as i64);
    let i = if wrap {
        i.rem_euclid(w)
    } else {
        i.clamp(0, w - 1)
    };
    Vec3::from(image.pixels[(j.clamp(0, h - 1) * w + i) as usize])
}

/// Where direction `d` falls in `view`'s image, in pixel units (as [`View::ray`] takes
/// them), and how central it is there (its cosine to the view's direction); `None` outside
/// the view.
fn in_view(view: &View, d: Vec3) -> Option<(f32, f32, f32)> {
    let along = d.dot(view.forward);
    // (NaN falls out here too.)
    if along.is_nan() || along <= 0.0 {
        return None;
    }
    let sx = d.dot(view.right_span) / (along * view.right_span.length_squared());
    let sy = d.dot(view.up_span) / (along * view.up_span.length_squared());
    let inside = |s: f32| (-0.5..=0.5).contains(&s);
    (inside(sx) && inside(sy)).then_some((
        (sx + 0.5) * view.width as f32,
        (0.5 - sy) * view.height as f32,
        along,
    ))
}

/// Where every view of `desc` is, as a panorama's views are: an error naming two views
/// apart (or a scene with none).
fn common_position(desc: &SceneDesc, objects: &[ObjObject]) -> Result<[f64; 3], Error> {
    let Some(first) = desc.views.first() else {
        return Err(Error::input(
            &desc.path,
            "has no view to take the panorama's position from: give --position",
        ));
    };
    let size = geometry_size(objects);
    match desc
        .views
        .iter()
        .find(|v| apart(v.position, first.position, size))
    {
        Some(v) => Err(Error::input(
            &desc.path,
            format!(
                "view '{}' is at {:?} and view '{}' at {:?}: a panorama is seen from one position",
                v.name, v.position, first.name, first.position
            ),
        )),
        None => Ok(first.position),
    }
}

/// The longest side of the objects' bounding box, in their files' 64-bit coordinates (0
/// without a vertex).
fn geometry_size(objects: &[ObjObject]) -> f64 {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in objects.iter().flat_map(|o| o.triangles.iter().flatten()) {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    (0..3).map(|k| hi[k] - lo[k]).fold(0.0, f64::max)
}

/// Whether two view positions are apart by more than rounding: by 1e-5 of the scene's
/// `size`, in whatever unit and wherever the scene is (positions are read in 64 bits). Of
/// their distance from the origin, as it was, views 2.7 units apart in a room 3 across
/// 270 km from its origin were one position. A scene of no size falls back to that.
fn apart(a: [f64; 3], b: [f64; 3], size: f64) -> bool {
    let length = |v: [f64; 3]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
    let scale = match size.is_finite() && size > 0.0 {
        true => size,
        false => length(a).max(length(b)),
    };
    length(std::array::from_fn(|k| a[k] - b[k])) > 1e-5 * scale
}

#[cfg(test)]
mod tests {
    use super::*;

    pub(super) fn z_up() -> Frame {
        Frame::new([1.0, 0.0, 0.0], [0.0, 0.0, 1.0]).unwrap()
    }

    /// Views a thousandth of a unit apart in a scene a few units across are apart, and so
    /// they are in the same scene scaled by 1e-3 or 1e3; rounding is not.
    #[test]
    fn view_positions_are_apart_relative_to_their_size() {
        for scale in [1e-3f64, 1.0, 1e3] {
            let p = [1.5 * scale, 0.9 * scale, 1.3 * scale];
            let moved = |d: f64| [p[0] + d * scale, p[1], p[2]];
            assert!(apart(p, moved(1e-3), 3.0 * scale), "{scale}");
            assert!(!apart(p, moved(1e-7), 3.0 * scale), "{scale}");
        }
        assert!(!apart([0.0; 3], [0.0; 3], 3.0));
        // A scene of no size: relative to the positions, as if they were its size.
        assert!(apart([0.0; 3], [1e-6, 0.0, 0.0], 0.0));
        assert!(!apart([1.0, 0.0, 0.0], [1.0 + 1e-7, 0.0, 0.0], 0.0));
        // A room 3 across, 270 km from its origin: a unit apart is apart.
        let far = [100_001.5, -249_999.1, 30_001.3];
        assert!(apart(far, [far[0] - 1.0, far[1], far[2]], 3.0));
        assert!(!apart(far, [far[0] + 1e-6, far[1], far[2]], 3.0));
    }

    /// A `--forward` off the horizon is projected onto it, and said so past a degree.
    #[test]
    fn a_forward_off_the_horizon_is_told_of() {
        let up = [0.0, 0.0, 1.0];
        let tilted = Frame::new([1.0, 0.0, 1.0], up).unwrap();
        assert_eq!(tilted.forward, Vec3::X);
        let said = tilted.tilt_warning([1.0, 0.0, 1.0]).unwrap();
        assert!(
            said.contains("--forward [1.0, 0.0, 1.0] is 45.0 degrees off the horizon")
                && said.contains("[1.000, 0.000, 0.000]"),
            "{said}"
        );
        let level = [1.0, 0.0, 0.01];
        assert_eq!(Frame::new(level, up).unwrap().tilt_warning(level), None);
    }

    #[test]
    fn the_centre_column_looks_forward_and_the_image_turns_to_the_right() {
        let f = z_up();
        let at = |d: [f32; 3]| f.image_position(Vec3::from(d).normalize());
        let close = |(u, v): (f32, f32), (eu, ev): (f32, f32)| {
            assert!((u - eu).abs() < 1e-6 && (v - ev).abs() < 1e-6, "{u} {v}");
        };
        close(at([1.0, 0.0, 0.0]), (0.5, 0.5));
        // Z up, forward +X: the right is -Y, a quarter turn to the right of the centre.
        assert_eq!(f.right, Vec3::new(0.0, -1.0, 0.0));
        close(at([0.0, -1.0, 0.0]), (0.75, 0.5));
        close(at([0.0, 1.0, 0.0]), (0.25, 0.5));
        close(at([0.0, 0.0, 1.0]), (0.5, 0.0));
        close(at([0.0, 0.0, -1.0]), (0.5, 1.0));
        close(at([1.0, 0.0, 1.0]), (0.5, 0.25));
        // Behind: either edge of the turn.
        let (u, v) = at([-1.0, 1e-7, 0.0]);
        assert!((u.min(1.0 - u)) < 1e-6 && (v - 0.5).abs() < 1e-6, "{u}");
    }

    #[test]
    fn a_forward_off_the_horizon_is_levelled_and_a_parallel_pair_refused() {
        let f = Frame::new([1.0, 0.0, 0.5], [0.0, 0.0, 2.0]).unwrap();
        assert!((f.forward - Vec3::X).length() < 1e-6 && (f.up - Vec3::Z).length() < 1e-6);
        for (forward, up) in [
            ([0.0, 0.0, 1.0], [0.0, 0.0, 1.0]),
            ([1.0, 0.0, 0.0], [0.0, 0.0, 0.0]),
            ([f32::NAN, 0.0, 0.0], [0.0, 0.0, 1.0]),
        ] {
            assert!(matches!(Frame::new(forward, up), Err(Error::Usage(_))));
        }
        // Tiny and huge vectors are directions like any other: their squared lengths
        // leave f32's range, which made a valid pair read "parallel or zero".
        for (forward, up) in [
            ([1e-30, 0.0, 1e-30], [1e-30, 1e-30, 1e-30]),
            ([1e30, 0.0, 0.0], [0.0, 0.0, 3e38]),
            ([f32::from_bits(1), 0.0, 0.0], [0.0, 0.0, 1.0]),
        ] {
            let f = Frame::new(forward, up).unwrap();
            assert!((f.up.length() - 1.0).abs() < 1e-6 && f.forward.dot(f.up).abs() < 1e-6);
        }
        let f = Frame::new([1e-30, 0.0, 0.0], [0.0, 0.0, 1e-30]).unwrap();
        assert_eq!((f.forward, f.up), (Vec3::X, Vec3::Z));
        // The scaling is exact: a pair already of unit size keeps its bits.
        let (forward, up) = ([0.3f32, -0.7, 0.2], [0.1f32, 0.2, 0.9]);
        let (plain_u, f) = (Vec3::from(up).normalize_or_zero(), Vec3::from(forward));
        let plain_f = (f - plain_u * f.dot(plain_u)).normalize_or_zero();
        let frame = Frame::new(forward, up).unwrap();
        assert_eq!((frame.forward, frame.up), (plain_f, plain_u));
    }
}
