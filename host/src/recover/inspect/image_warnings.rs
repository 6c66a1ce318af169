//! Warnings of the panorama's images themselves, before any render: grey images, a view's
//! image repeated under another view, and pixels clipped at the format's top.

use crate::images::Image;
use crate::recover::pixels::PurePixel;
use crate::scene_file::ViewDesc;

/// A view whose pixels all hold equal R, G and B, and not all 0: a greyscale capture (a
/// grey PNG is read as three equal channels), from which every colour comes out grey. A
/// colour capture of the greyest room differs between its channels somewhere, if only by
/// noise. (A grey PNG of a red wall gave a grey wall without a word.)
pub(super) fn greyscale_warnings(real: &[Image], view_names: &[String]) -> Vec<String> {
    real.iter()
        .zip(view_names)
        .filter(|(image, _)| {
            image.pixels.iter().all(|&[r, g, b]| r == g && g == b)
                && image.pixels.iter().any(|p| p[0] > 0.0)
        })
        .map(|(_, name)| {
            format!(
                "view '{name}' holds equal R, G and B in every pixel (a greyscale image?): the groups it sees are fitted to grey, and come out grey where no colour view sees them"
            )
        })
        .collect()
}

/// A view that looks from the same place, the same way, over the same field and pixels
/// as an earlier one: every fit counts its pixels twice (a copied `[[view]]` table lifted
/// a 2-pixel plate to 4, and it came out glossy). Told, naming both.
pub(super) fn repeated_view_warnings(views: &[ViewDesc]) -> Vec<String> {
    let same = |a: &ViewDesc, b: &ViewDesc| {
        a.position == b.position
            && a.direction == b.direction
            && a.up == b.up
            && a.fov_deg == b.fov_deg
            && a.size == b.size
    };
    views
        .iter()
        .enumerate()
        .filter_map(|(i, v)| {
            let first = views[..i].iter().find(|u| same(u, v))?;
            Some(format!(
                "view '{}' looks from where view '{}' does, the same way, over the same field and pixels: every fit counts these pixels twice, weighing what they see double; leave one out (or merge their images)",
                v.name, first.name
            ))
        })
        .collect()
}

/// A PNG view's pure pixels clipped at its largest code are at least that bright, not
/// that: counted per view, and told where there are any. (A capture's 6 pixels at 65535
/// were taken as radiance without a word.)
pub(super) fn clipped_warnings(
    pure: &[PurePixel],
    real: &[Image],
    clipped_at: &[Option<f32>],
    view_names: &[String],
) -> Vec<String> {
    let mut clipped = vec![0u32; real.len()];
    let mut seen = vec![0u32; real.len()];
    for p in pure {
        let v = p.view as usize;
        seen[v] += 1;
        if let Some(level) = clipped_at[v] {
            let image = &real[v];
            if image.pixels[(p.y * image.width + p.x) as usize]
                .iter()
                .any(|&c| c >= level)
            {
                clipped[v] += 1;
            }
        }
    }
    (0..real.len())
        .filter(|&v| clipped[v] > 0)
        .map(|v| {
            format!(
                "view '{}': {} of {} pure pixels are at its PNG's largest value in some channel (clipped): their radiance is at least that, and the colours fitted to them come out dark; a high-dynamic-range capture (.exr, .hdr) or a shorter exposure keeps them",
                view_names[v],
                clipped[v],
                seen[v]
            )
        })
        .collect()
}
