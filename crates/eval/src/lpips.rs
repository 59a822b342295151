//! LPIPS (Zhang et al. 2018) with the AlexNet backbone, on weights converted once by
//! `scripts/fetch-lpips.sh` (nothing is downloaded at run time).

use std::path::{Path, PathBuf};

use burn::tensor::module::{conv2d, max_pool2d};
use burn::tensor::ops::{ConvOptions, MaxPoolOptions};
use burn::tensor::{Device, Tensor, TensorData};
use image::Rgb32FImage;

/// Environment variable naming the folder with `alexnet.bin` and `alexnet.json`.
pub const LPIPS_ENV: &str = "SUPERSVG_LPIPS";

/// The LPIPS weights could not be read; the message names the file and what is wrong with it.
#[derive(Debug, thiserror::Error)]
#[error("{message}")]
pub struct LpipsError {
    /// What went wrong, with the file.
    pub message: String,
}

/// The LPIPS network: AlexNet's five convolutions and the five linear heads.
pub struct Lpips {
    convs: Vec<(Tensor<4>, Tensor<1>)>,
    heads: Vec<Tensor<4>>,
    device: Device,
}

/// Stride and padding of AlexNet's five convolutions.
const LAYERS: [(usize, usize); 5] = [(4, 2), (1, 2), (1, 1), (1, 1), (1, 1)];

impl Lpips {
    /// The folder the weights are read from: `$SUPERSVG_LPIPS`, else `models/lpips` of the source
    /// tree this program was built from.
    pub fn default_folder() -> PathBuf {
        std::env::var_os(LPIPS_ENV)
            .map(PathBuf::from)
            .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("../../models/lpips"))
    }

    /// Loads the converted weights from `folder`.
    pub fn load(folder: &Path, device: &Device) -> Result<Self, LpipsError> {
        Self::read(folder, device).map_err(|message| LpipsError { message })
    }

    /// [`Lpips::load`], its messages naming the file at fault.
    fn read(folder: &Path, device: &Device) -> Result<Self, String> {
        let index_path = folder.join("alexnet.json");
        let index: serde_json::Value = std::fs::read_to_string(&index_path)
            .map_err(|err| format!("{}: {err} (run scripts/fetch-lpips.sh)", index_path.display()))
            .and_then(|text| {
                serde_json::from_str(&text).map_err(|err| format!("{}: {err}", index_path.display()))
            })?;
        let blob_path = folder.join("alexnet.bin");
        let blob = std::fs::read(&blob_path).map_err(|err| format!("{}: {err}", blob_path.display()))?;
        let tensor = |name: &str| -> Result<(Vec<usize>, Vec<f32>), String> {
            let entry = &index[name];
            let shape: Vec<usize> = entry["shape"]
                .as_array()
                .ok_or_else(|| format!("{}: no tensor {name}", index_path.display()))?
                .iter()
                .map(|d| d.as_u64().unwrap_or(0) as usize)
                .collect();
            let offset = entry["offset"].as_u64().unwrap_or(0) as usize;
            let len = shape.iter().product::<usize>() * 4;
            let bytes = blob
                .get(offset..offset + len)
                .ok_or_else(|| format!("{}: truncated", blob_path.display()))?;
            Ok((shape, bytes.chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect()))
        };
        let four = |name: &str| -> Result<Tensor<4>, String> {
            let (shape, values) = tensor(name)?;
            let dims: [usize; 4] = shape.try_into().map_err(|_| format!("{name} is not 4-D"))?;
            Ok(Tensor::from_data(TensorData::new(values, dims), device))
        };
        let mut convs = Vec::new();
        let mut heads = Vec::new();
        for layer in 0..LAYERS.len() {
            let (_, bias) = tensor(&format!("conv{layer}.bias"))?;
            convs.push((four(&format!("conv{layer}.weight"))?, Tensor::from_floats(bias.as_slice(), device)));
            heads.push(four(&format!("head{layer}.weight"))?);
        }
        Ok(Self { convs, heads, device: device.clone() })
    }

    /// LPIPS distance between two images of the same size (0 for identical images, higher is
    /// more different).
    pub fn distance(&self, a: &Rgb32FImage, b: &Rgb32FImage) -> f64 {
        let (fa, fb) = (self.features(a), self.features(b));
        let mut total = 0.0;
        for ((xa, xb), head) in fa.into_iter().zip(fb).zip(&self.heads) {
            let difference = (unit_norm(xa) - unit_norm(xb)).square();
            let weighted =
                conv2d(difference, head.clone(), None, ConvOptions::new([1, 1], [0, 0], [1, 1], 1));
            total += weighted.mean().into_scalar::<f32>() as f64;
        }
        total
    }

    /// The five ReLU activations of AlexNet for an image scaled to [−1, 1] and LPIPS's input
    /// normalization.
    fn features(&self, image: &Rgb32FImage) -> Vec<Tensor<4>> {
        let (width, height) = image.dimensions();
        let planar: Vec<f32> = (0..3).flat_map(|c| image.pixels().map(move |p| p.0[c])).collect();
        let x = Tensor::<4>::from_data(
            TensorData::new(planar, [1, 3, height as usize, width as usize]),
            &self.device,
        );
        let shift = Tensor::<1>::from_floats([-0.030, -0.088, -0.188], &self.device).reshape([1, 3, 1, 1]);
        let scale = Tensor::<1>::from_floats([0.458, 0.448, 0.450], &self.device).reshape([1, 3, 1, 1]);
        let mut x = (x * 2.0 - 1.0 - shift) / scale;
        let mut outputs = Vec::new();
        for (layer, ((weight, bias), (stride, padding))) in self.convs.iter().zip(LAYERS).enumerate() {
            let options = ConvOptions::new([stride, stride], [padding, padding], [1, 1], 1);
            x = conv2d(x, weight.clone(), Some(bias.clone()), options).clamp_min(0.0);
            outputs.push(x.clone());
            if layer < 2 {
                x = max_pool2d(x, MaxPoolOptions::new([3, 3]).with_stride([2, 2]));
            }
        }
        outputs
    }
}

/// Features divided by their norm over channels (LPIPS's `normalize_tensor`, ε = 1e−10).
fn unit_norm(x: Tensor<4>) -> Tensor<4> {
    let norm = x.clone().square().sum_dim(1).sqrt() + 1e-10;
    x / norm
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Against the numpy implementation in scripts/fetch-lpips.sh, on the pair it uses.
    #[test]
    #[ignore = "needs the LPIPS weights: scripts/fetch-lpips.sh, then cargo test -p eval -- --ignored (CI does)"]
    fn matches_the_reference_implementation() {
        let folder = Lpips::default_folder();
        let lpips = Lpips::load(&folder, &Device::flex()).unwrap_or_else(|err| panic!("{err}"));
        let reference: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(folder.join("reference.json")).unwrap()).unwrap();
        let (a, b) = infer::metrics::test_pair(80, 64);
        let expected = reference["lpips"].as_f64().unwrap();
        let got = lpips.distance(&a, &b);
        assert!((got - expected).abs() < 1e-4 * expected.max(1.0), "{got} vs {expected}");
        assert!(lpips.distance(&a, &a).abs() < 1e-9);
    }
}
