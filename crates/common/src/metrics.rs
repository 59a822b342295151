//! Image quality measures between a rendering and its target.

use std::ops::Range;

use image::Rgb32FImage;
use rayon::prelude::*;

/// Mean squared error over all pixels and channels (values in [0, 1]).
pub fn mse(a: &Rgb32FImage, b: &Rgb32FImage) -> f64 {
    assert_eq!(a.dimensions(), b.dimensions(), "images of different sizes");
    let sum: f64 = a.as_raw().iter().zip(b.as_raw()).map(|(x, y)| (*x as f64 - *y as f64).powi(2)).sum();
    sum / a.as_raw().len() as f64
}

/// The smallest mean squared error PSNR tells apart: 1e-10 is 100 dB, far past what 8-bit
/// pictures can show (one level in 255 everywhere is 48 dB), so equal images read 100 dB
/// instead of infinity.
const MSE_FLOOR: f64 = 1e-10;

/// Peak signal-to-noise ratio in dB for values in [0, 1] of a mean squared error, at most
/// 100 dB (see [`MSE_FLOOR`]): every PSNR the project reports goes through here.
pub fn psnr_of_mse(mse: f64) -> f64 {
    -10.0 * mse.max(MSE_FLOOR).log10()
}

/// Peak signal-to-noise ratio in dB between two images with values in [0, 1] ([`psnr_of_mse`]).
pub fn psnr(a: &Rgb32FImage, b: &Rgb32FImage) -> f64 {
    psnr_of_mse(mse(a, b))
}

/// Gradient magnitude similarity deviation (Xue et al. 2014; lower is better): the standard
/// deviation, over pixels, of how alike the two images' gradient magnitudes are, on their
/// luminance (ITU-R 601, in 0..255) averaged over 2×2 blocks, with 3×3 Prewitt filters and
/// the paper's constant c = 170. False edges a drawing adds, and edges it blurs, raise it;
/// a flat colour that is slightly off does not.
pub fn gmsd(reference: &Rgb32FImage, drawn: &Rgb32FImage) -> f64 {
    assert_eq!(reference.dimensions(), drawn.dimensions(), "images of different sizes");
    let luminance = |image: &Rgb32FImage| -> (Vec<f64>, usize, usize) {
        let (width, height) = (image.width() as usize / 2, image.height() as usize / 2);
        let at = |x: usize, y: usize| {
            let p = image.get_pixel(x as u32, y as u32).0;
            255.0 * (0.299 * f64::from(p[0]) + 0.587 * f64::from(p[1]) + 0.114 * f64::from(p[2]))
        };
        let values = (0..height)
            .flat_map(|y| (0..width).map(move |x| (x, y)))
            .map(|(x, y)| {
                (at(2 * x, 2 * y) + at(2 * x + 1, 2 * y) + at(2 * x, 2 * y + 1) + at(2 * x + 1, 2 * y + 1))
                    / 4.0
            })
            .collect();
        (values, width, height)
    };
    let magnitudes = |(values, width, height): &(Vec<f64>, usize, usize)| -> Vec<f64> {
        let at = |x: usize, y: usize| values[y * width + x];
        let mut out = Vec::with_capacity(width.saturating_sub(2) * height.saturating_sub(2));
        for y in 1..height.saturating_sub(1) {
            for x in 1..width - 1 {
                let gx = (at(x + 1, y - 1) + at(x + 1, y) + at(x + 1, y + 1)
                    - at(x - 1, y - 1)
                    - at(x - 1, y)
                    - at(x - 1, y + 1))
                    / 3.0;
                let gy = (at(x - 1, y + 1) + at(x, y + 1) + at(x + 1, y + 1)
                    - at(x - 1, y - 1)
                    - at(x, y - 1)
                    - at(x + 1, y - 1))
                    / 3.0;
                out.push(gx.hypot(gy));
            }
        }
        out
    };
    const C: f64 = 170.0;
    let (a, b) = (magnitudes(&luminance(reference)), magnitudes(&luminance(drawn)));
    if a.is_empty() {
        return 0.0;
    }
    let similarity: Vec<f64> =
        a.iter().zip(&b).map(|(a, b)| (2.0 * a * b + C) / (a * a + b * b + C)).collect();
    let mean = similarity.iter().sum::<f64>() / similarity.len() as f64;
    (similarity.iter().map(|s| (s - mean).powi(2)).sum::<f64>() / similarity.len() as f64).sqrt()
}

/// Structural similarity (Wang et al. 2004) as scikit-image computes it with
/// `gaussian_weights=True, sigma=1.5, use_sample_covariance=False, data_range=1`: local means,
/// variances and covariance under an 11×11 Gaussian window (σ = 1.5), K1 = 0.01, K2 = 0.03,
/// averaged over the pixels whose window lies inside the image and over the three channels.
/// An image narrower than the window (where scikit-image refuses) gets the widest window that
/// fits, down to a single pixel, so every image has a score.
pub fn ssim(a: &Rgb32FImage, b: &Rgb32FImage) -> f64 {
    assert_eq!(a.dimensions(), b.dimensions(), "images of different sizes");
    let (width, height) = (a.width() as usize, a.height() as usize);
    let radius = 5usize.min((width.min(height).max(1) - 1) / 2);
    let weights: Vec<f64> = {
        let raw: Vec<f64> = (0..=2 * radius)
            .map(|i| (-((i as f64 - radius as f64).powi(2)) / (2.0 * 1.5 * 1.5)).exp())
            .collect();
        let total: f64 = raw.iter().sum();
        raw.into_iter().map(|w| w / total).collect()
    };
    let (inner_width, inner_height) = (width - 2 * radius, height - 2 * radius);
    // Bands of output rows, each filtered from its own rows of the images: memory stays a few
    // bands' worth whatever the image's size, and the bands' sums are added in order, so the
    // score does not depend on how the threads shared them.
    let bands: Vec<f64> = (0..inner_height.div_ceil(SSIM_BAND))
        .into_par_iter()
        .map(|band| {
            let rows = band * SSIM_BAND..((band + 1) * SSIM_BAND).min(inner_height);
            (0..3).map(|channel| ssim_band(a, b, channel, rows.clone(), &weights)).sum::<f64>()
        })
        .collect();
    bands.iter().sum::<f64>() / (3 * inner_width * inner_height) as f64
}

/// Output rows [`ssim`] computes together: 64 rows of an 8192-pixel-wide image keep five
/// quantities in about 25 MB.
const SSIM_BAND: usize = 64;

/// The sum of SSIM over the output rows `rows` of one channel: the five Gaussian-weighted
/// moments (means, second moments, cross moment) of every window whose top row is in `rows`.
/// Each pass runs along contiguous rows of one moment at a time, so it compiles to vector code;
/// every window's sums are added in the same order as one window at a time would add them.
fn ssim_band(a: &Rgb32FImage, b: &Rgb32FImage, channel: usize, rows: Range<usize>, weights: &[f64]) -> f64 {
    let (c1, c2) = (0.01f64.powi(2), 0.03f64.powi(2));
    let width = a.width() as usize;
    let span = weights.len();
    let inner_width = width + 1 - span;
    let (x, y) = (a.as_raw(), b.as_raw());
    // Horizontal pass over every image row the band's windows reach, one plane per moment:
    // [μx, μy, xx, yy, xy].
    let input_rows = rows.start..rows.end + span - 1;
    let mut horizontal: [Vec<f64>; 5] = std::array::from_fn(|_| vec![0.0; input_rows.len() * inner_width]);
    let mut values: [Vec<f64>; 5] = std::array::from_fn(|_| vec![0.0; width]);
    for (r, row) in input_rows.enumerate() {
        for column in 0..width {
            let index = 3 * (row * width + column) + channel;
            let (p, q) = (x[index] as f64, y[index] as f64);
            for (plane, v) in values.iter_mut().zip([p, q, p * p, q * q, p * q]) {
                plane[column] = v;
            }
        }
        for (plane, out) in values.iter().zip(&mut horizontal) {
            let out = &mut out[r * inner_width..(r + 1) * inner_width];
            for (k, w) in weights.iter().enumerate() {
                for (o, v) in out.iter_mut().zip(&plane[k..k + inner_width]) {
                    *o += w * v;
                }
            }
        }
    }
    let mut sum = 0.0;
    let mut m: [Vec<f64>; 5] = std::array::from_fn(|_| vec![0.0; inner_width]);
    for r in 0..rows.len() {
        for (out, plane) in m.iter_mut().zip(&horizontal) {
            out.fill(0.0);
            for (k, w) in weights.iter().enumerate() {
                let row = &plane[(r + k) * inner_width..(r + k + 1) * inner_width];
                for (o, v) in out.iter_mut().zip(row) {
                    *o += w * v;
                }
            }
        }
        for column in 0..inner_width {
            let [mx, my, xx, yy, xy] = [0, 1, 2, 3, 4].map(|i| m[i][column]);
            let (vx, vy, cov) = (xx - mx * mx, yy - my * my, xy - mx * my);
            sum += ((2.0 * mx * my + c1) * (2.0 * cov + c2)) / ((mx * mx + my * my + c1) * (vx + vy + c2));
        }
    }
    sum
}

/// A fixed pair of test images (for metric tests here and in other crates), `width × height`: a pattern and a dimmed, wavy copy of it. The
/// reference values of the metric tests (scikit-image, and numpy's LPIPS in
/// scripts/fetch-lpips.sh) were computed on the same formula.
pub fn test_pair(width: u32, height: u32) -> (Rgb32FImage, Rgb32FImage) {
    use image::Rgb;
    let value = |x: u32, y: u32, c: u32| ((x * 7 + y * 3 + c * 5) % 11) as f64 / 10.0;
    let a = Rgb32FImage::from_fn(width, height, |x, y| {
        Rgb(std::array::from_fn(|c| value(x, y, c as u32) as f32))
    });
    let b = Rgb32FImage::from_fn(width, height, |x, y| {
        Rgb(std::array::from_fn(|c| {
            let v = value(x, y, c as u32) * 0.8 + 0.1 * (x as f64 * 0.7 + y as f64 * 0.3 + c as f64).sin();
            v.clamp(0.0, 1.0) as f32
        }))
    });
    (a, b)
}

#[cfg(test)]
mod gmsd_tests {
    use image::{Rgb, Rgb32FImage};

    /// An image is its own perfect match; a blurred edge and a false edge each raise it, and a
    /// slightly darker flat image barely does.
    #[test]
    fn gmsd_sees_edges_not_flat_offsets() {
        let step = Rgb32FImage::from_fn(64, 64, |x, _| Rgb([if x < 32 { 0.1 } else { 0.9 }; 3]));
        assert_eq!(super::gmsd(&step, &step), 0.0);
        let blurred =
            Rgb32FImage::from_fn(64, 64, |x, _| Rgb([(0.1 + 0.8 * (x as f32 / 63.0)).clamp(0.0, 1.0); 3]));
        let false_edge = Rgb32FImage::from_fn(64, 64, |x, y| {
            let base = if x < 32 { 0.1 } else { 0.9 };
            Rgb([if y == 20 { base + 0.3 } else { base }; 3])
        });
        let darker = Rgb32FImage::from_fn(64, 64, |x, _| Rgb([if x < 32 { 0.08 } else { 0.88 }; 3]));
        let (blur, edge, dark) =
            (super::gmsd(&step, &blurred), super::gmsd(&step, &false_edge), super::gmsd(&step, &darker));
        assert!(blur > 0.05 && edge > 0.05 && dark < 0.01, "{blur} {edge} {dark}");
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The pair of images the reference values were computed on, with scikit-image 0.24:
    /// `structural_similarity(a, b, gaussian_weights=True, sigma=1.5,
    /// use_sample_covariance=False, data_range=1.0, channel_axis=2)` and
    /// `peak_signal_noise_ratio(a, b, data_range=1.0)`.
    fn pair() -> (Rgb32FImage, Rgb32FImage) {
        test_pair(23, 17)
    }

    #[test]
    fn matches_scikit_image() {
        let (a, b) = pair();
        let ssim = ssim(&a, &b);
        assert!((ssim - 0.9291021452537022).abs() < 1e-6, "{ssim}");
        assert!((psnr(&a, &b) - 17.195980230211408).abs() < 1e-4, "{}", psnr(&a, &b));
    }

    #[test]
    fn identical_images_are_perfect() {
        let (a, _) = pair();
        assert!((ssim(&a, &a) - 1.0).abs() < 1e-12);
        assert_eq!(mse(&a, &a), 0.0);
        assert_eq!(psnr(&a, &a), 100.0);
        assert_eq!(psnr_of_mse(0.01), 20.0);
        // Narrower than the window: a smaller window, down to one pixel.
        for (w, h) in [(5, 40), (1, 30), (1, 1)] {
            let (x, y) = (test_pair(w, h).0, Rgb32FImage::from_pixel(w, h, image::Rgb([0.5; 3])));
            assert!((ssim(&x, &x) - 1.0).abs() < 1e-12, "{w}×{h}");
            let score = ssim(&x, &y);
            assert!(score.is_finite() && score < 1.0, "{w}×{h}: {score}");
        }
    }
}
