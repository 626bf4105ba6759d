//! Inline SVG plots: the loss curve of a part's fit.

use std::fmt::Write;

use crate::html::num;

const WIDTH: f64 = 360.0;
const HEIGHT: f64 = 140.0;
/// Room for the axis labels.
const LEFT: f64 = 56.0;
const BOTTOM: f64 = 20.0;
const TOP: f64 = 8.0;
const RIGHT: f64 = 8.0;

/// The loss per recorded step as a polyline; the y axis is logarithmic when the values span more
/// than a factor of 20 (and are all positive). `None` when fewer than two values are finite.
pub fn loss_curve(values: &[f64]) -> Option<String> {
    let finite: Vec<(usize, f64)> = values.iter().copied().enumerate().filter(|(_, v)| v.is_finite()).collect();
    if finite.len() < 2 {
        return None;
    }
    let lo = finite.iter().map(|p| p.1).fold(f64::INFINITY, f64::min);
    let hi = finite.iter().map(|p| p.1).fold(f64::NEG_INFINITY, f64::max);
    let log = lo > 0.0 && hi / lo > 20.0;
    let t = |v: f64| if log { v.log10() } else { v };
    let (tlo, thi) = (t(lo), t(hi));
    let span = if thi > tlo { thi - tlo } else { 1.0 };
    let last = (values.len() - 1).max(1) as f64;
    let x = |i: usize| LEFT + (WIDTH - LEFT - RIGHT) * i as f64 / last;
    let y = |v: f64| TOP + (HEIGHT - TOP - BOTTOM) * (1.0 - (t(v) - tlo) / span);
    let mut points = String::new();
    for (i, v) in &finite {
        let _ = write!(points, "{:.1},{:.1} ", x(*i), y(*v));
    }
    let mut s = format!(
        "<svg class=\"plot\" width=\"{WIDTH}\" height=\"{HEIGHT}\" \
         viewBox=\"0 0 {WIDTH} {HEIGHT}\" role=\"img\" aria-label=\"loss curve\">"
    );
    let (x0, x1, y0, y1) = (LEFT, WIDTH - RIGHT, TOP, HEIGHT - BOTTOM);
    let _ = write!(
        s,
        "<rect x=\"{x0}\" y=\"{y0}\" width=\"{}\" height=\"{}\" fill=\"#fafafa\" stroke=\"#bbb\"/>",
        x1 - x0,
        y1 - y0
    );
    let _ =
        write!(s, "<polyline fill=\"none\" stroke=\"#c0392b\" stroke-width=\"1.5\" points=\"{}\"/>", points.trim_end());
    let label = |s: &mut String, xx: f64, yy: f64, anchor: &str, text: &str| {
        let _ = write!(s, "<text x=\"{xx:.1}\" y=\"{yy:.1}\" font-size=\"10\" text-anchor=\"{anchor}\">{text}</text>");
    };
    label(&mut s, x0 - 4.0, y0 + 8.0, "end", &num(hi));
    label(&mut s, x0 - 4.0, y1, "end", &num(lo));
    label(&mut s, x0, HEIGHT - 6.0, "start", "0");
    label(
        &mut s,
        x1,
        HEIGHT - 6.0,
        "end",
        &format!("{} steps{}", values.len() - 1, if log { ", log scale" } else { "" }),
    );
    s.push_str("</svg>");
    Some(s)
}

#[cfg(test)]
mod tests {
    use super::loss_curve;

    #[test]
    fn plots_every_finite_value_and_picks_the_scale() {
        let s = loss_curve(&[1.0, 0.5, f64::NAN, 0.01]).unwrap();
        let points = s.split("points=\"").nth(1).unwrap().split('"').next().unwrap();
        assert_eq!(points.split(' ').count(), 3, "{s}"); // three points, the NaN left out
        assert!(s.contains("log scale"));
        let s = loss_curve(&[0.3, 0.2, 0.1]).unwrap();
        assert!(!s.contains("log scale"));
        assert!(loss_curve(&[0.3]).is_none());
        assert!(loss_curve(&[f64::NAN, 0.3]).is_none());
    }
}
