//! A `[[view]]`: its values checked into a [`ViewDesc`] (a frame, a field of view, a size
//! within [`MAX_VIEW_SIDE`], a positive exposure), and the core's view made of it.

use crate::error::Error;

use super::raw::RawView;
use super::{TomlFile, ViewDesc, MAX_VIEW_SIDE};

impl ViewDesc {
    /// The core's view (its frame checked and precomputed).
    pub fn view(&self) -> Result<relume_core::geometry::View, relume_core::Error> {
        use glam::Vec3;
        relume_core::geometry::View::new(
            Vec3::from(self.position.map(|x| x as f32)),
            Vec3::from(self.direction),
            Vec3::from(self.up),
            self.fov_deg,
            self.size,
        )
    }
}

pub(super) fn check_view(file: &TomlFile, v: &RawView) -> Result<ViewDesc, Error> {
    let name = file.identifier(&v.name, "view name")?;
    let image = match &v.image {
        Some(i) => Some(file.resolve(&file.name(i, "image")?)),
        None => None,
    };
    let position: [f64; 3] = file.vector64(&v.position, "position")?;
    let direction: [f32; 3] = file.direction(&v.direction, "direction")?;
    let up: [f32; 3] = file.direction(&v.up, "up")?;
    let fov_deg: [f32; 2] = file.vector(&v.fov_deg, "fov_deg")?;
    let d = direction.map(f64::from);
    let u = up.map(f64::from);
    let dd = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
    let uu = u[0] * u[0] + u[1] * u[1] + u[2] * u[2];
    if dd == 0.0 {
        return Err(file.at(
            v.direction.span(),
            format!("view '{name}': direction is zero"),
        ));
    }
    let c = [
        d[1] * u[2] - d[2] * u[1],
        d[2] * u[0] - d[0] * u[2],
        d[0] * u[1] - d[1] * u[0],
    ];
    if c[0] * c[0] + c[1] * c[1] + c[2] * c[2] <= 1e-12 * dd * uu {
        return Err(file.at(
            v.up.span(),
            format!("view '{name}': up {up:?} is zero or parallel to direction {direction:?}"),
        ));
    }
    if fov_deg.iter().any(|&f| !(f > 0.0 && f < 180.0)) {
        return Err(file.at(
            v.fov_deg.span(),
            format!("view '{name}': fov_deg must be in (0, 180) degrees, got {fov_deg:?}"),
        ));
    }
    let s = v.size.get_ref();
    if s.len() != 2 {
        return Err(file.at(
            v.size.span(),
            format!(
                "view '{name}': size must have 2 integers (width, height), found {}",
                s.len()
            ),
        ));
    }
    if s.iter().any(|&x| !(1..=MAX_VIEW_SIDE).contains(&x)) {
        return Err(file.at(
            v.size.span(),
            format!("view '{name}': size must be between 1 and {MAX_VIEW_SIDE} pixels, got {s:?}"),
        ));
    }
    let size = [s[0] as u32, s[1] as u32];
    let exposure = match &v.exposure {
        Some(e) => {
            let x = file.number(e, "exposure")?;
            if x <= 0.0 {
                return Err(file.at(
                    e.span(),
                    format!("view '{name}': exposure must be > 0, got {x}"),
                ));
            }
            x
        }
        None => 1.0,
    };
    Ok(ViewDesc {
        name,
        image,
        position,
        direction,
        up,
        fov_deg,
        size,
        exposure,
    })
}

#[cfg(test)]
mod tests {
    use crate::scene_file::tests::bad;

    #[test]
    fn exposure_must_be_positive() {
        bad(
            "exposure = 1.0",
            "exposure = 0.0",
            14,
            &["view 'front'", "exposure must be > 0"],
        );
        bad(
            "exposure = 1.0",
            "exposure = -2",
            14,
            &["exposure must be > 0"],
        );
        // Below f32's range the value written is not the value meant: say so.
        bad(
            "exposure = 1.0",
            "exposure = 1e-50",
            14,
            &["`exposure` is too small for a 32-bit float, which reads 1e-50 as 0"],
        );
    }

    #[test]
    fn size_must_be_at_least_1() {
        bad(
            "size = [8, 8]",
            "size = [0, 8]",
            13,
            &["view 'front'", "size must be between 1 and"],
        );
        bad(
            "size = [8, 8]",
            "size = [8, -1]",
            13,
            &["size must be between 1 and"],
        );
        bad(
            "size = [8, 8]",
            "size = [8, 16385]",
            13,
            &["size must be between 1 and 16384"],
        );
    }

    #[test]
    fn fov_must_be_in_0_180() {
        for fov in [
            "[0.0, 60.0]",
            "[60.0, 180.0]",
            "[-10.0, 60.0]",
            "[60.0, 200.0]",
        ] {
            bad(
                "fov_deg = [60.0, 60.0]",
                &format!("fov_deg = {fov}"),
                12,
                &["fov_deg must be in (0, 180)"],
            );
        }
    }

    #[test]
    fn direction_and_up_must_make_a_frame() {
        bad(
            "direction = [0.0, 1.0, 0.0]",
            "direction = [0.0, 0.0, 0.0]",
            10,
            &["direction is zero"],
        );
        bad(
            "up = [0.0, 0.0, 1.0]",
            "up = [0.0, 2.0, 0.0]",
            11,
            &["parallel to direction"],
        );
        bad(
            "up = [0.0, 0.0, 1.0]",
            "up = [0.0, 0.0, 0.0]",
            11,
            &["zero or parallel"],
        );
    }
}
