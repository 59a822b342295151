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
pub enum LpipsError {
    /// A weights file could not be read.
    #[error("{}: {source} (run scripts/fetch-lpips.sh)", path.display())]
    Read {
        /// `alexnet.json` or `alexnet.bin`.
        path: PathBuf,
        /// The reason.
        source: std::io::Error,
    },
    /// The index is not JSON.
    #[error("{}: {source}", path.display())]
    Index {
        /// `alexnet.json`.
        path: PathBuf,
        /// The parser's reason.
        source: serde_json::Error,
    },
    /// The index names no such tensor, or gives it a shape of another rank.
    #[error("{}: no {rank}-D tensor `{name}`", path.display())]
    MissingTensor {
        /// `alexnet.json`.
        path: PathBuf,
        /// The tensor.
        name: String,
        /// The rank it must have.
        rank: usize,
    },
    /// The tensor lies past the end of the weights.
    #[error("{}: truncated (tensor `{name}`)", path.display())]
    Truncated {
        /// `alexnet.bin`.
        path: PathBuf,
        /// The first tensor that does not fit.
        name: String,
    },
}

/// The LPIPS network: AlexNet's five convolutions and the five linear heads.
pub struct Lpips {
    convs: Vec<(Tensor<4>, Tensor<1>)>,
    heads: Vec<Tensor<4>>,
    device: Device,
}

/// Stride and padding of AlexNet's five convolutions.
const LAYERS: [(usize, usize); 5] = [(4, 2), (1, 2), (1, 1), (1, 1), (1, 1)];

/// The max-pooling window after the first two convolutions (stride 2).
const POOL: usize = 3;

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
        let index_path = folder.join("alexnet.json");
        let read_error = |path: &Path| {
            let path = path.to_path_buf();
            move |source| LpipsError::Read { path, source }
        };
        let text = std::fs::read_to_string(&index_path).map_err(read_error(&index_path))?;
        let index: serde_json::Value = serde_json::from_str(&text)
            .map_err(|source| LpipsError::Index { path: index_path.clone(), source })?;
        let blob_path = folder.join("alexnet.bin");
        let blob = std::fs::read(&blob_path).map_err(read_error(&blob_path))?;
        // The shape and values of tensor `name`, which must have `rank` dimensions.
        let tensor = |name: &str, rank: usize| -> Result<(Vec<usize>, Vec<f32>), LpipsError> {
            let entry = &index[name];
            let missing =
                || LpipsError::MissingTensor { path: index_path.clone(), name: name.to_string(), rank };
            let shape: Vec<usize> = entry["shape"]
                .as_array()
                .ok_or_else(missing)?
                .iter()
                .map(|d| d.as_u64().map(|d| d as usize).ok_or_else(missing))
                .collect::<Result<_, _>>()?;
            if shape.len() != rank {
                return Err(missing());
            }
            let offset = entry["offset"].as_u64().ok_or_else(missing)? as usize;
            let truncated = || LpipsError::Truncated { path: blob_path.clone(), name: name.to_string() };
            let len = shape.iter().try_fold(4usize, |n, &d| n.checked_mul(d)).ok_or_else(truncated)?;
            let bytes =
                offset.checked_add(len).and_then(|end| blob.get(offset..end)).ok_or_else(truncated)?;
            Ok((shape, bytes.chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect()))
        };
        let four = |name: &str| -> Result<Tensor<4>, LpipsError> {
            let (shape, values) = tensor(name, 4)?;
            let dims = [shape[0], shape[1], shape[2], shape[3]];
            Ok(Tensor::from_data(TensorData::new(values, dims), device))
        };
        let mut convs = Vec::new();
        let mut heads = Vec::new();
        for layer in 0..LAYERS.len() {
            let (_, bias) = tensor(&format!("conv{layer}.bias"), 1)?;
            convs.push((four(&format!("conv{layer}.weight"))?, Tensor::from_floats(bias.as_slice(), device)));
            heads.push(four(&format!("head{layer}.weight"))?);
        }
        Ok(Self { convs, heads, device: device.clone() })
    }

    /// LPIPS distance between two images of the same size (0 for identical images, higher is
    /// more different); `None` for an image too small for AlexNet's layers to see (under
    /// [`Lpips::smallest_side`] pixels a side), where LPIPS is not defined.
    pub fn distance(&self, a: &Rgb32FImage, b: &Rgb32FImage) -> Option<f64> {
        let (width, height) = a.dimensions();
        if width.min(height) < self.smallest_side() {
            return None;
        }
        let (fa, fb) = (self.features(a), self.features(b));
        let mut total = 0.0;
        for ((xa, xb), head) in fa.into_iter().zip(fb).zip(&self.heads) {
            let difference = (unit_norm(xa) - unit_norm(xb)).square();
            let weighted =
                conv2d(difference, head.clone(), None, ConvOptions::new([1, 1], [0, 0], [1, 1], 1));
            total += weighted.mean().into_scalar::<f32>() as f64;
        }
        Some(total)
    }

    /// The shortest image side every layer of the network still has a pixel of output for.
    pub fn smallest_side(&self) -> u32 {
        (1..).find(|&side| self.output_side(side).is_some()).expect("some side fits")
    }

    /// The side of the last layer's output for an input `side` pixels wide; `None` where a
    /// convolution's kernel or a pooling window no longer fits.
    fn output_side(&self, side: u32) -> Option<u32> {
        let mut side = side as usize;
        for (layer, ((weight, _), (stride, padding))) in self.convs.iter().zip(LAYERS).enumerate() {
            let kernel = weight.dims()[2];
            side = (side + 2 * padding).checked_sub(kernel)? / stride + 1;
            if layer < 2 {
                side = side.checked_sub(POOL)? / 2 + 1;
            }
        }
        Some(side as u32)
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
                x = max_pool2d(x, MaxPoolOptions::new([POOL, POOL]).with_stride([2, 2]));
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

    /// Each way a weights folder can be damaged gives its own error, naming the file.
    #[test]
    fn damaged_weights_are_named() {
        let dir = std::env::temp_dir().join(format!("supersvg-lpips-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let load = || Lpips::load(&dir, &Device::flex()).err().expect("damaged weights are refused");

        let err = load();
        assert!(matches!(err, LpipsError::Read { .. }) && err.to_string().contains("alexnet.json"), "{err}");
        std::fs::write(dir.join("alexnet.json"), "{ not json").unwrap();
        std::fs::write(dir.join("alexnet.bin"), [0u8; 8]).unwrap();
        let err = load();
        assert!(matches!(err, LpipsError::Index { .. }), "{err}");
        std::fs::write(dir.join("alexnet.json"), r#"{"conv0.bias": {"shape": [2, 2], "offset": 0}}"#)
            .unwrap();
        let err = load();
        assert!(matches!(err, LpipsError::MissingTensor { rank: 1, .. }), "{err}");
        std::fs::write(dir.join("alexnet.json"), r#"{"conv0.bias": {"shape": [4], "offset": 0}}"#).unwrap();
        let err = load();
        assert!(
            matches!(err, LpipsError::Truncated { .. }) && err.to_string().contains("alexnet.bin"),
            "{err}"
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// Against the numpy implementation in scripts/fetch-lpips.sh, on the pair it uses.
    #[test]
    #[ignore = "needs the LPIPS weights: scripts/fetch-lpips.sh, then cargo test -p eval -- --ignored (CI does)"]
    fn matches_the_reference_implementation() {
        let folder = Lpips::default_folder();
        let lpips = Lpips::load(&folder, &Device::flex()).unwrap_or_else(|err| panic!("{err}"));
        let reference: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(folder.join("reference.json")).unwrap()).unwrap();
        let (a, b) = common::metrics::test_pair(80, 64);
        let expected = reference["lpips"].as_f64().unwrap();
        let got = lpips.distance(&a, &b).expect("80 × 64 is large enough");
        assert!((got - expected).abs() < 1e-4 * expected.max(1.0), "{got} vs {expected}");
        assert!(lpips.distance(&a, &a).expect("the same size").abs() < 1e-9);
    }

    /// AlexNet needs 31 pixels a side (11-px stride-4 convolution, then two 3-px poolings);
    /// below that LPIPS is not defined and is said as such, not a panic in the convolution.
    #[test]
    #[ignore = "needs the LPIPS weights: scripts/fetch-lpips.sh, then cargo test -p eval -- --ignored (CI does)"]
    fn lpips_of_an_image_too_small_is_none() {
        let lpips =
            Lpips::load(&Lpips::default_folder(), &Device::flex()).unwrap_or_else(|err| panic!("{err}"));
        assert_eq!(lpips.smallest_side(), 31);
        let (a, b) = common::metrics::test_pair(31, 40);
        assert!(lpips.distance(&a, &b).is_some_and(|d| d > 0.0));
        let (a, b) = common::metrics::test_pair(30, 40);
        assert_eq!(lpips.distance(&a, &b), None);
        let (a, b) = common::metrics::test_pair(24, 16);
        assert_eq!(lpips.distance(&a, &b), None);
    }
}
