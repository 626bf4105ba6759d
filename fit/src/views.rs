//! Multi-view: which photo each part is fitted to. As PhotoScene's supplement describes, a view
//! scores its coverage of the part (usable pixels) × a centre weighting (parts near the image
//! centre are less distorted and less vignetted; a Gaussian around the centre) × consensus (the
//! part's shading-normalised median colour in this view agrees with the other views'; a view
//! with a specular highlight or a misaligned mask disagrees).

use serde::Serialize;

use crate::align::AlignedPart;
use crate::observe::ViewObservation;

/// The score of one view for one part.
#[derive(Clone, Debug, Serialize, serde::Deserialize)]
pub struct ViewScore {
    pub view: String,
    pub usable_pixels: usize,
    pub coverage: f32,
    pub centre: f32,
    pub consensus: f32,
    pub score: f32,
}

/// Standard deviation of the centre weighting, in units of the half-diagonal.
const CENTRE_SIGMA: f32 = 0.6;
/// Colour difference (linear RGB distance, relative to the median's brightness) at which the
/// consensus weight falls to 1/e.
const CONSENSUS_SCALE: f32 = 0.25;

/// Scores the candidate views of one part. `candidates[i]` is the part's alignment in view
/// `candidates[i].view` and `albedo[i]` its shading-normalised median colour there. Returns
/// the scores in candidate order and the index of the best.
pub fn choose(views: &[ViewObservation], candidates: &[&AlignedPart], albedo: &[[f32; 3]]) -> (Vec<ViewScore>, usize) {
    let max_usable = candidates.iter().map(|a| a.usable.len()).max().unwrap_or(0).max(1);
    let consensus_colour: [f32; 3] = [0, 1, 2].map(|c| {
        let mut v: Vec<f32> = albedo.iter().map(|a| a[c]).collect();
        crate::lighting::median(&mut v)
    });
    let brightness = consensus_colour.iter().sum::<f32>().max(1e-3) / 3.0;
    let scores: Vec<ViewScore> = candidates
        .iter()
        .zip(albedo)
        .map(|(a, colour)| {
            let obs = &views[a.view];
            let (w, h) = (obs.photo.width as f32, obs.photo.height as f32);
            let half_diagonal = 0.5 * (w * w + h * h).sqrt();
            let centre = if a.usable.is_empty() {
                0.0
            } else {
                a.usable
                    .iter()
                    .map(|&i| {
                        let (x, y) =
                            ((i as usize % obs.photo.width) as f32 + 0.5, (i as usize / obs.photo.width) as f32 + 0.5);
                        let r = ((x - w / 2.0).powi(2) + (y - h / 2.0).powi(2)).sqrt() / half_diagonal;
                        (-r * r / (2.0 * CENTRE_SIGMA * CENTRE_SIGMA)).exp()
                    })
                    .sum::<f32>()
                    / a.usable.len() as f32
            };
            let distance = (0..3).map(|c| (colour[c] - consensus_colour[c]).powi(2)).sum::<f32>().sqrt() / brightness;
            let consensus = if candidates.len() > 1 { (-distance / CONSENSUS_SCALE).exp() } else { 1.0 };
            let coverage = a.usable.len() as f32 / max_usable as f32;
            ViewScore {
                view: obs.name.clone(),
                usable_pixels: a.usable.len(),
                coverage,
                centre,
                consensus,
                score: coverage * centre * consensus,
            }
        })
        .collect();
    let best = (0..scores.len()).reduce(|a, b| if scores[b].score > scores[a].score { b } else { a }).unwrap_or(0);
    (scores, best)
}
