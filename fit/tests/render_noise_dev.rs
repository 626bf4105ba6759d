//! The render-noise check tells a photo's pixel noise from its finest texture on the dev scenes:
//! the crop of a photo-textured wall (dev_1's gravel, dev_3's bricks, whose noise estimates read
//! two to three times those of the plain parts beside them) has its estimate cut, while every
//! plain part keeps its own, dev_1's ceiling included: lit only by bounces, it is as noisy as
//! the gravel wall, and a photo-wide noise level would have called that noise texture.

mod dev_part_views;
#[path = "../../tests/src/not_run.rs"]
mod not_run;

/// Per part of the scene's first view with at least 2000 usable pixels: its name, true texture
/// kind and the factor the check puts on its crop's noise estimate.
fn noise_factors(name: &str) -> Option<Vec<(String, String, f32)>> {
    let parts = dev_part_views::first_view_parts(name, "render_noise_dev", 2000)?;
    Some(parts.into_iter().map(|p| (p.name, p.kind, p.view.noise_scale)).collect())
}

#[test]
fn photo_textures_lose_noise_and_plain_parts_keep_theirs() {
    for (scene, textured) in [("dev_1", "walls"), ("dev_3", "walls_b")] {
        let Some(factors) = noise_factors(scene) else { continue };
        eprintln!("{scene}: {factors:?}");
        let (_, _, f) = factors.iter().find(|(p, _, _)| p == textured).expect("the wall is seen");
        assert!(*f < 0.8, "{scene}: {textured}'s noise estimate kept {f} of itself: {factors:?}");
        let plain: Vec<_> = factors.iter().filter(|(_, k, _)| k == "plain").collect();
        assert!(plain.len() >= 2, "{scene}: {factors:?}");
        for (part, _, f) in plain {
            assert!(*f > 0.95, "{scene}: the plain {part}'s noise estimate was cut to {f} of itself: {factors:?}");
        }
    }
}
