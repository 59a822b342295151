//! Image quality measures between a rendering and its target.

use image::Rgb32FImage;

/// Mean squared error over all pixels and channels (values in [0, 1]).
pub fn mse(a: &Rgb32FImage, b: &Rgb32FImage) -> f64 {
    assert_eq!(a.dimensions(), b.dimensions(), "images of different sizes");
    let sum: f64 = a.as_raw().iter().zip(b.as_raw()).map(|(x, y)| (*x as f64 - *y as f64).powi(2)).sum();
    sum / a.as_raw().len() as f64
}

/// Peak signal-to-noise ratio in dB for values in [0, 1] (capped at 100 dB for equal images).
pub fn psnr(a: &Rgb32FImage, b: &Rgb32FImage) -> f64 {
    (-10.0 * mse(a, b).log10()).min(100.0)
}

/// Structural similarity (Wang et al. 2004) as scikit-image computes it with
/// `gaussian_weights=True, sigma=1.5, use_sample_covariance=False, data_range=1`: local means,
/// variances and covariance under an 11×11 Gaussian window (σ = 1.5), K1 = 0.01, K2 = 0.03,
/// averaged over the pixels whose window lies inside the image and over the three channels.
/// Images smaller than the window give `None`.
pub fn ssim(a: &Rgb32FImage, b: &Rgb32FImage) -> Option<f64> {
    assert_eq!(a.dimensions(), b.dimensions(), "images of different sizes");
    const RADIUS: usize = 5;
    let (width, height) = (a.width() as usize, a.height() as usize);
    if width <= 2 * RADIUS || height <= 2 * RADIUS {
        return None;
    }
    let weights: Vec<f64> = {
        let raw: Vec<f64> = (0..=2 * RADIUS)
            .map(|i| (-((i as f64 - RADIUS as f64).powi(2)) / (2.0 * 1.5 * 1.5)).exp())
            .collect();
        let total: f64 = raw.iter().sum();
        raw.into_iter().map(|w| w / total).collect()
    };
    let (c1, c2) = (0.01f64.powi(2), 0.03f64.powi(2));
    let mut total = 0.0;
    for channel in 0..3 {
        let x: Vec<f64> = a.pixels().map(|p| p.0[channel] as f64).collect();
        let y: Vec<f64> = b.pixels().map(|p| p.0[channel] as f64).collect();
        let product =
            |f: &dyn Fn(f64, f64) -> f64| x.iter().zip(&y).map(|(&p, &q)| f(p, q)).collect::<Vec<f64>>();
        let filtered = |values: &[f64]| window_means(values, width, height, &weights);
        let (mx, my) = (filtered(&x), filtered(&y));
        let (xx, yy, xy) = (
            filtered(&product(&|p, _| p * p)),
            filtered(&product(&|_, q| q * q)),
            filtered(&product(&|p, q| p * q)),
        );
        let mut sum = 0.0;
        for i in 0..mx.len() {
            let (vx, vy, cov) = (xx[i] - mx[i] * mx[i], yy[i] - my[i] * my[i], xy[i] - mx[i] * my[i]);
            sum += ((2.0 * mx[i] * my[i] + c1) * (2.0 * cov + c2))
                / ((mx[i] * mx[i] + my[i] * my[i] + c1) * (vx + vy + c2));
        }
        total += sum / mx.len() as f64;
    }
    Some(total / 3.0)
}

/// Gaussian-weighted means over every full window, `(width − 2r) × (height − 2r)` values.
fn window_means(values: &[f64], width: usize, height: usize, weights: &[f64]) -> Vec<f64> {
    let r = weights.len() / 2;
    let inner_width = width - 2 * r;
    let mut rows = vec![0.0; height * inner_width];
    for y in 0..height {
        for x in 0..inner_width {
            rows[y * inner_width + x] =
                weights.iter().enumerate().map(|(k, w)| w * values[y * width + x + k]).sum();
        }
    }
    let inner_height = height - 2 * r;
    let mut out = vec![0.0; inner_height * inner_width];
    for y in 0..inner_height {
        for x in 0..inner_width {
            out[y * inner_width + x] =
                weights.iter().enumerate().map(|(k, w)| w * rows[(y + k) * inner_width + x]).sum();
        }
    }
    out
}

/// A fixed pair of test images, `width × height`: a pattern and a dimmed, wavy copy of it. The
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
        let ssim = ssim(&a, &b).unwrap();
        assert!((ssim - 0.9291021452537022).abs() < 1e-6, "{ssim}");
        assert!((psnr(&a, &b) - 17.195980230211408).abs() < 1e-4, "{}", psnr(&a, &b));
    }

    #[test]
    fn identical_images_are_perfect() {
        let (a, _) = pair();
        assert!((ssim(&a, &a).unwrap() - 1.0).abs() < 1e-12);
        assert_eq!(mse(&a, &a), 0.0);
        assert_eq!(psnr(&a, &a), 100.0);
        assert!(ssim(&Rgb32FImage::new(5, 40), &Rgb32FImage::new(5, 40)).is_none());
    }
}
