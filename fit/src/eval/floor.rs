//! What the parts no input view shows cost a row: the part of the fitted / pixel-median ratio
//! that no fit of the photographed parts can remove.
//!
//! A part no input view shows keeps the fit's documented default, and the pixel median gives it
//! the median of all labelled pixels; neither has seen it. A row averages over every (image,
//! part) pair, so such a part's error enters the fitted row whatever the fit does with the
//! rest. The floor of a ratio is the fitted row with every photographed part scored 0, over
//! the pixel median's row: a fitted ratio cannot fall below it unless the unseen part happens
//! to be guessed (its errors move with the rest only through interreflections). On dev_4 a
//! striped wall no input view shows puts the floor of the true geometry's novel-view contrast
//! ratio at 0.65, above the target of 0.5.

use super::{Geometry, ImageResult, Method, Row, ViewKind};

/// The floor of the fitted / pixel-median ratios of one (geometry, view kind), per metric.
#[derive(Clone, Debug, PartialEq)]
pub struct UnseenFloor {
    pub geometry: Geometry,
    pub kind: ViewKind,
    pub rmse: f64,
    pub mean_colour: f64,
    pub colour_w1: f64,
    pub contrast_w1: f64,
}

/// One floor per (geometry, view kind) whose fitted images hold a part of `unseen` and that
/// has a pixel-median row, in the rows' order.
pub fn unseen_floors(images: &[ImageResult], rows: &[Row], unseen: &[String]) -> Vec<UnseenFloor> {
    let fitted_rows = rows.iter().filter(|r| r.method == Method::Fitted);
    fitted_rows
        .filter_map(|fitted| {
            let baseline = rows
                .iter()
                .find(|r| (r.geometry, r.kind, r.method) == (fitted.geometry, fitted.kind, Method::PixelMedian))?;
            let parts: Vec<_> = images
                .iter()
                .filter(|im| (im.geometry, im.kind, im.method) == (fitted.geometry, fitted.kind, Method::Fitted))
                .flat_map(|im| &im.parts)
                .collect();
            let is_unseen = |part: &str| unseen.iter().any(|u| u == part);
            if !parts.iter().any(|p| is_unseen(&p.part)) {
                return None;
            }
            // The row's own mean, with every photographed part's term replaced by 0.
            let share = |value: &dyn Fn(&super::PartMetrics) -> Option<f64>| {
                let (mut sum, mut count) = (0.0, 0usize);
                for p in &parts {
                    if let Some(v) = value(p) {
                        count += 1;
                        if is_unseen(&p.part) {
                            sum += v;
                        }
                    }
                }
                if count == 0 {
                    f64::NAN
                } else {
                    sum / count as f64
                }
            };
            Some(UnseenFloor {
                geometry: fitted.geometry,
                kind: fitted.kind,
                rmse: share(&|p| Some(p.rmse)) / baseline.rmse,
                mean_colour: share(&|p| Some(p.mean_colour)) / baseline.mean_colour,
                colour_w1: share(&|p| Some(p.colour_w1)) / baseline.colour_w1,
                contrast_w1: share(&|p| p.contrast_w1) / baseline.contrast_w1,
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::eval::{aggregate, PartMetrics};

    fn part(name: &str, value: f64, contrast: Option<f64>) -> PartMetrics {
        PartMetrics {
            part: name.into(),
            pixels: 1000,
            rmse: value,
            mean_colour: value,
            colour_w1: value,
            contrast_w1: contrast,
        }
    }

    fn image(method: Method, kind: ViewKind, view: &str, parts: Vec<PartMetrics>) -> ImageResult {
        ImageResult {
            geometry: Geometry::Truth,
            method,
            kind,
            view: view.into(),
            width: 1,
            height: 1,
            ssim: Some(0.5),
            parts,
            render: vec![[0.0; 3]],
        }
    }

    #[test]
    fn the_floor_is_the_unseen_parts_share_of_the_fitted_row_over_the_baseline() {
        let images = vec![
            // Two novel images: the wall is in both, the lamp (no contrast sample) in one.
            image(
                Method::Fitted,
                ViewKind::Novel,
                "a",
                vec![part("wall", 0.3, Some(0.03)), part("floor", 0.1, Some(0.01))],
            ),
            image(Method::Fitted, ViewKind::Novel, "b", vec![part("wall", 0.5, Some(0.05)), part("lamp", 0.2, None)]),
            image(
                Method::PixelMedian,
                ViewKind::Novel,
                "a",
                vec![part("wall", 0.4, Some(0.04)), part("floor", 0.2, Some(0.02))],
            ),
            image(
                Method::PixelMedian,
                ViewKind::Novel,
                "b",
                vec![part("wall", 0.6, Some(0.06)), part("lamp", 0.4, None)],
            ),
            // Input views show only photographed parts: no floor.
            image(Method::Fitted, ViewKind::Input, "v", vec![part("floor", 0.1, Some(0.01))]),
            image(Method::PixelMedian, ViewKind::Input, "v", vec![part("floor", 0.2, Some(0.02))]),
        ];
        let rows = aggregate(&images);
        let floors = unseen_floors(&images, &rows, &["wall".to_string(), "ceiling".to_string()]);
        assert_eq!(floors.len(), 1);
        let f = &floors[0];
        assert_eq!((f.geometry, f.kind), (Geometry::Truth, ViewKind::Novel));
        // RMSE: (0.3 + 0.5) / 4 pairs over the baseline's (0.4 + 0.2 + 0.6 + 0.4) / 4.
        assert!((f.rmse - 0.8 / 1.6).abs() < 1e-12, "{f:?}");
        // Contrast: three pairs have a sample; (0.03 + 0.05) / 3 over (0.04 + 0.02 + 0.06) / 3.
        assert!((f.contrast_w1 - 0.08 / 0.12).abs() < 1e-12, "{f:?}");
        // With the fitted wall perfect, the floor is 0.
        let mut perfect = images.clone();
        for im in perfect.iter_mut().filter(|im| im.method == Method::Fitted) {
            for p in im.parts.iter_mut().filter(|p| p.part == "wall") {
                *p = part("wall", 0.0, Some(0.0));
            }
        }
        let rows = aggregate(&perfect);
        let floors = unseen_floors(&perfect, &rows, &["wall".to_string()]);
        assert_eq!((floors[0].rmse, floors[0].contrast_w1), (0.0, 0.0));
        // No unseen part, no floor.
        assert!(unseen_floors(&images, &aggregate(&images), &[]).is_empty());
    }
}
