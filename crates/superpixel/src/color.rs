//! Colour conversion and pre-smoothing for SLIC.

use rayon::prelude::*;

/// D65 reference white (2° observer), as scikit-image uses.
const WHITE: [f32; 3] = [0.950_47, 1.0, 1.088_83];

/// CIELAB of an sRGB colour with channels in [0, 1].
pub(crate) fn srgb_to_lab([r, g, b]: [f32; 3]) -> [f32; 3] {
    let (r, g, b) = (linear(r), linear(g), linear(b));
    let x = (0.412_453 * r + 0.357_580 * g + 0.180_423 * b) / WHITE[0];
    let y = (0.212_671 * r + 0.715_160 * g + 0.072_169 * b) / WHITE[1];
    let z = (0.019_334 * r + 0.119_193 * g + 0.950_227 * b) / WHITE[2];
    let f = |t: f32| if t > 0.008_856 { cbrt(t) } else { 7.787 * t + 16.0 / 116.0 };
    let (fx, fy, fz) = (f(x), f(y), f(z));
    [116.0 * fy - 16.0, 500.0 * (fx - fy), 200.0 * (fy - fz)]
}

/// Entries of the sRGB decoding table over [0, 1].
const GAMMA_STEPS: usize = 4096;

/// sRGB decoding (gamma 2.4 with a linear toe), by linear interpolation in a table (error below
/// 1e−6, far under what SLIC can see) instead of a `powf` per channel.
fn linear(c: f32) -> f32 {
    static TABLE: std::sync::OnceLock<Vec<f32>> = std::sync::OnceLock::new();
    let table = TABLE.get_or_init(|| {
        (0..=GAMMA_STEPS)
            .map(|i| {
                let c = i as f64 / GAMMA_STEPS as f64;
                (if c > 0.04045 { ((c + 0.055) / 1.055).powf(2.4) } else { c / 12.92 }) as f32
            })
            .collect()
    });
    let position = c.clamp(0.0, 1.0) * GAMMA_STEPS as f32;
    let index = (position as usize).min(GAMMA_STEPS - 1);
    let fraction = position - index as f32;
    table[index] + fraction * (table[index + 1] - table[index])
}

/// Cube root of a positive number: a bit-level first guess refined by three Newton steps
/// (relative error below 1e−6), faster than `f32::cbrt`.
fn cbrt(x: f32) -> f32 {
    let guess = f32::from_bits(x.to_bits() / 3 + 709_921_077);
    let step = |y: f32| y - (y * y * y - x) / (3.0 * y * y);
    step(step(step(guess)))
}

/// Gaussian blur of one `width × height` plane with standard deviation `sigma` pixels (kernel
/// truncated at 4σ, mirrored borders, as scipy's `gaussian_filter`).
///
/// Both passes add whole shifted rows times one weight at a time, which the compiler turns into
/// vector code.
pub(crate) fn gaussian_blur(plane: &[f32], width: usize, height: usize, sigma: f32) -> Vec<f32> {
    if sigma <= 0.0 {
        return plane.to_vec();
    }
    let radius = (4.0 * sigma).ceil() as usize;
    let mut kernel: Vec<f32> = (0..=2 * radius)
        .map(|i| (-((i as f32 - radius as f32).powi(2)) / (2.0 * sigma * sigma)).exp())
        .collect();
    let total: f32 = kernel.iter().sum();
    kernel.iter_mut().for_each(|k| *k /= total);

    let mut horizontal = vec![0.0f32; plane.len()];
    horizontal.par_chunks_mut(width).enumerate().for_each(|(y, out)| {
        let row = &plane[y * width..(y + 1) * width];
        let padded: Vec<f32> =
            (0..width + 2 * radius).map(|x| row[mirror(x as isize - radius as isize, width)]).collect();
        for (k, w) in kernel.iter().enumerate() {
            out.iter_mut().zip(&padded[k..k + width]).for_each(|(o, v)| *o += w * v);
        }
    });
    let mut vertical = vec![0.0f32; plane.len()];
    vertical.par_chunks_mut(width).enumerate().for_each(|(y, out)| {
        for (k, w) in kernel.iter().enumerate() {
            let source = mirror(y as isize + k as isize - radius as isize, height);
            out.iter_mut()
                .zip(&horizontal[source * width..(source + 1) * width])
                .for_each(|(o, v)| *o += w * v);
        }
    });
    vertical
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
    fn fast_paths_match_the_exact_functions() {
        for i in 0..=1000 {
            let c = i as f32 / 1000.0;
            let exact = if c > 0.04045 { ((c + 0.055) / 1.055).powf(2.4) } else { c / 12.92 };
            assert!((linear(c) - exact).abs() < 2e-6, "{c}: {} vs {exact}", linear(c));
            let t = 0.008 + c * 1.2;
            assert!((cbrt(t) - t.cbrt()).abs() < 1e-6 * t.cbrt(), "{t}");
        }
    }

    #[test]
    fn blur_preserves_constants_and_mass() {
        let (w, h) = (7, 5);
        let flat = vec![0.5; w * h];
        assert!(gaussian_blur(&flat, w, h, 1.5).iter().all(|p| (p - 0.5).abs() < 1e-6));
        let mut dot = vec![0.0; 21 * 21];
        dot[10 * 21 + 10] = 1.0;
        let blurred = gaussian_blur(&dot, 21, 21, 1.0);
        let mass: f32 = blurred.iter().sum();
        assert!((mass - 1.0).abs() < 1e-4);
        assert!(blurred[10 * 21 + 11] < blurred[10 * 21 + 10]);
        assert!((blurred[10 * 21 + 11] - blurred[11 * 21 + 10]).abs() < 1e-7, "isotropic");
    }
}
