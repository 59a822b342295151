//! Colour conversion and pre-smoothing for SLIC.

use rayon::prelude::*;

/// D65 reference white (2° observer), as scikit-image uses.
const WHITE: [f32; 3] = [0.950_47, 1.0, 1.088_83];

/// CIELAB of an sRGB colour with channels in [0, 1].
pub(crate) fn srgb_to_lab([r, g, b]: [f32; 3]) -> [f32; 3] {
    let linear = |c: f32| if c > 0.04045 { ((c + 0.055) / 1.055).powf(2.4) } else { c / 12.92 };
    let (r, g, b) = (linear(r), linear(g), linear(b));
    let x = (0.412_453 * r + 0.357_580 * g + 0.180_423 * b) / WHITE[0];
    let y = (0.212_671 * r + 0.715_160 * g + 0.072_169 * b) / WHITE[1];
    let z = (0.019_334 * r + 0.119_193 * g + 0.950_227 * b) / WHITE[2];
    let f = |t: f32| if t > 0.008_856 { t.cbrt() } else { 7.787 * t + 16.0 / 116.0 };
    let (fx, fy, fz) = (f(x), f(y), f(z));
    [116.0 * fy - 16.0, 500.0 * (fx - fy), 200.0 * (fy - fz)]
}

/// Gaussian blur of an interleaved `width × height × 3` buffer with standard deviation `sigma`
/// pixels (kernel truncated at 4σ, mirrored borders, as scipy's `gaussian_filter`).
pub(crate) fn gaussian_blur(pixels: &[[f32; 3]], width: usize, height: usize, sigma: f32) -> Vec<[f32; 3]> {
    if sigma <= 0.0 {
        return pixels.to_vec();
    }
    let radius = (4.0 * sigma).ceil() as isize;
    let mut kernel: Vec<f32> =
        (-radius..=radius).map(|i| (-(i * i) as f32 / (2.0 * sigma * sigma)).exp()).collect();
    let total: f32 = kernel.iter().sum();
    kernel.iter_mut().for_each(|k| *k /= total);
    let mut horizontal = vec![[0.0f32; 3]; pixels.len()];
    horizontal.par_chunks_mut(width).enumerate().for_each(|(y, row)| {
        let source = &pixels[y * width..(y + 1) * width];
        for (x, out) in row.iter_mut().enumerate() {
            *out = weighted_sum(&kernel, |k| source[mirror(x as isize + k - radius, width)]);
        }
    });
    let mut vertical = vec![[0.0f32; 3]; pixels.len()];
    vertical.par_chunks_mut(width).enumerate().for_each(|(y, row)| {
        for (x, out) in row.iter_mut().enumerate() {
            *out = weighted_sum(&kernel, |k| horizontal[mirror(y as isize + k - radius, height) * width + x]);
        }
    });
    vertical
}

/// `Σ_k kernel[k] · sample(k)` per channel.
fn weighted_sum(kernel: &[f32], sample: impl Fn(isize) -> [f32; 3]) -> [f32; 3] {
    let mut acc = [0.0f32; 3];
    for (k, weight) in kernel.iter().enumerate() {
        let p = sample(k as isize);
        for c in 0..3 {
            acc[c] += weight * p[c];
        }
    }
    acc
}

/// Index `i` reflected into `0..n` (`… c b a | a b c … | c b a …`, scipy's "reflect").
fn mirror(i: isize, n: usize) -> usize {
    let n = n as isize;
    let m = i.rem_euclid(2 * n);
    (if m < n { m } else { 2 * n - 1 - m }) as usize
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lab_matches_reference_values() {
        // Reference values from scikit-image's rgb2lab.
        let close = |a: [f32; 3], b: [f32; 3]| a.iter().zip(b).all(|(x, y)| (x - y).abs() < 0.05);
        assert!(close(srgb_to_lab([1.0, 1.0, 1.0]), [100.0, 0.0, 0.0]), "{:?}", srgb_to_lab([1.0; 3]));
        assert!(close(srgb_to_lab([0.0, 0.0, 0.0]), [0.0, 0.0, 0.0]));
        assert!(
            close(srgb_to_lab([1.0, 0.0, 0.0]), [53.24, 80.09, 67.20]),
            "{:?}",
            srgb_to_lab([1.0, 0.0, 0.0])
        );
        assert!(
            close(srgb_to_lab([0.0, 0.0, 1.0]), [32.30, 79.19, -107.86]),
            "{:?}",
            srgb_to_lab([0.0, 0.0, 1.0])
        );
    }

    #[test]
    fn blur_preserves_constants_and_mass() {
        let (w, h) = (7, 5);
        let flat = vec![[0.25, 0.5, 1.0]; w * h];
        assert!(gaussian_blur(&flat, w, h, 1.5).iter().all(|p| (p[1] - 0.5).abs() < 1e-6));
        let mut dot = vec![[0.0; 3]; 21 * 21];
        dot[10 * 21 + 10] = [1.0; 3];
        let blurred = gaussian_blur(&dot, 21, 21, 1.0);
        let mass: f32 = blurred.iter().map(|p| p[0]).sum();
        assert!((mass - 1.0).abs() < 1e-4);
        assert!(blurred[10 * 21 + 11][0] < blurred[10 * 21 + 10][0]);
    }
}
