//! Rate and distortion: methods compared at equal file size rather than at equal path count.
//! A method swept over its settings gives points (mean SVG kilobytes, mean quality); another
//! method's quality at those sizes is read off its own curve, interpolated in log kilobytes,
//! so "better than vtracer" means better at every file size vtracer reaches.

/// One setting of a method, averaged over a set of images.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RatePoint {
    /// Mean SVG size, in kilobytes (1000 bytes).
    pub kilobytes: f64,
    /// Mean PSNR, in dB (higher is better).
    pub psnr: f64,
    /// Mean LPIPS (lower is better), when it was measured.
    pub lpips: Option<f64>,
}

/// The points no other point beats on `quality` (higher is better; points without it are left
/// out): none smaller, or as small, scores higher. Sorted by size; quality rises along it.
pub fn frontier(points: &[RatePoint], quality: impl Fn(&RatePoint) -> Option<f64>) -> Vec<RatePoint> {
    let mut scored: Vec<(RatePoint, f64)> = points
        .iter()
        .filter_map(|p| quality(p).map(|q| (*p, q)))
        .filter(|(p, _)| p.kilobytes.is_finite())
        .collect();
    scored.sort_by(|(a, qa), (b, qb)| a.kilobytes.total_cmp(&b.kilobytes).then(qb.total_cmp(qa)));
    let mut kept: Vec<(RatePoint, f64)> = Vec::new();
    for (point, score) in scored {
        if kept.last().is_none_or(|(_, best)| score > *best) {
            kept.push((point, score));
        }
    }
    kept.into_iter().map(|(point, _)| point).collect()
}

/// A curve's value at `kilobytes`: `value` of its points (sorted by size), linear in log size
/// between the two around it. `None` outside the sizes it covers, or where the value is
/// missing: a curve is not extrapolated.
pub fn at(curve: &[RatePoint], kilobytes: f64, value: impl Fn(&RatePoint) -> Option<f64>) -> Option<f64> {
    let mut sorted: Vec<RatePoint> = curve.to_vec();
    sorted.sort_by(|a, b| a.kilobytes.total_cmp(&b.kilobytes));
    let (first, last) = (sorted.first()?, sorted.last()?);
    if !(first.kilobytes..=last.kilobytes).contains(&kilobytes) {
        return None;
    }
    let above = sorted.iter().position(|p| p.kilobytes >= kilobytes)?;
    let high = &sorted[above];
    if above == 0 || high.kilobytes == kilobytes {
        return value(high);
    }
    let low = &sorted[above - 1];
    let t = (kilobytes.ln() - low.kilobytes.ln()) / (high.kilobytes.ln() - low.kilobytes.ln());
    Some(value(low)? + t * (value(high)? - value(low)?))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn point(kilobytes: f64, psnr: f64) -> RatePoint {
        RatePoint { kilobytes, psnr, lpips: Some(1.0 / psnr) }
    }

    #[test]
    fn the_frontier_drops_points_a_smaller_file_beats() {
        let points =
            [point(50.0, 30.0), point(10.0, 20.0), point(20.0, 19.0), point(40.0, 31.0), point(10.0, 21.0)];
        let kept: Vec<(f64, f64)> =
            frontier(&points, |p| Some(p.psnr)).iter().map(|p| (p.kilobytes, p.psnr)).collect();
        assert_eq!(kept, [(10.0, 21.0), (40.0, 31.0)]);
        // Lower LPIPS is better: negated, the same rule applies (here LPIPS = 1 / PSNR).
        let kept: Vec<f64> = frontier(&points, |p| p.lpips.map(|l| -l)).iter().map(|p| p.kilobytes).collect();
        assert_eq!(kept, [10.0, 40.0]);
        let unscored = [RatePoint { lpips: None, ..point(5.0, 40.0) }, point(10.0, 20.0)];
        assert_eq!(frontier(&unscored, |p| p.lpips.map(|l| -l)).len(), 1);
    }

    #[test]
    fn a_curve_is_read_in_log_size_and_never_extrapolated() {
        let curve = [point(100.0, 30.0), point(10.0, 20.0)];
        let psnr = |p: &RatePoint| Some(p.psnr);
        assert_eq!(at(&curve, 10.0, psnr), Some(20.0));
        assert_eq!(at(&curve, 100.0, psnr), Some(30.0));
        let middle = at(&curve, 10f64.powf(1.5), psnr).unwrap();
        assert!((middle - 25.0).abs() < 1e-9, "{middle}");
        assert_eq!(at(&curve, 9.9, psnr), None);
        assert_eq!(at(&curve, 101.0, psnr), None);
        assert_eq!(at(&[], 10.0, psnr), None);
        let lpips = at(&curve, 100.0, |p| p.lpips).unwrap();
        assert!((lpips - 1.0 / 30.0).abs() < 1e-12);
        let without = [RatePoint { lpips: None, ..point(10.0, 20.0) }, point(100.0, 30.0)];
        assert_eq!(at(&without, 50.0, |p| p.lpips), None);
    }
}
