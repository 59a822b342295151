//! What the integration tests share: small untrained networks of a fixed seed, and a folder
//! with their checkpoints and a photo for the `infer` program. (Each test file uses a part.)
#![allow(dead_code)]

use std::path::PathBuf;
use std::process::{Command, Output};

use burn::tensor::{DType, Device};
use image::{Rgb, RgbImage};
use model::{Checkpoint, CoarseModel, ModelConfig, OperatingPoint, Preset, RefineModel, Stage};

/// The `infer` program.
pub const INFER: &str = env!("CARGO_BIN_EXE_infer");

/// The CPU preset shrunk so a test draws in milliseconds; same architecture.
pub fn tiny_config() -> ModelConfig {
    ModelConfig {
        input_size: 32,
        embed_dim: 32,
        depth: 1,
        heads: 2,
        paths: 8,
        query_dim: 16,
        query_heads: 2,
        ..ModelConfig::preset(Preset::Cpu)
    }
}

/// E_c and E_r of [`tiny_config`], initialized from seed 1 on `device`.
pub fn tiny_models(device: &Device) -> (ModelConfig, CoarseModel, RefineModel) {
    let config = tiny_config();
    device.seed(1);
    let coarse = CoarseModel::new(&config, device);
    let refine = RefineModel::new(&config, device);
    (config, coarse, refine)
}

/// A scratch folder with a tiny coarse and refinement checkpoint and a photo.
pub struct Fixture {
    dir: PathBuf,
}

impl Fixture {
    /// A fresh folder for the test `name`.
    pub fn new(name: &str) -> Self {
        let dir = std::env::temp_dir().join(format!("supersvg-infer-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let (config, coarse, refine) = tiny_models(&Device::flex());
        // An operating point with a share for E_r, so that `--refine` and `--no-refine` matter.
        let point = OperatingPoint { refine_share: 0.1, ..OperatingPoint::default() };
        let checkpoint = Checkpoint::of_model(Stage::Coarse, &config, &coarse, DType::F16);
        Checkpoint { inference: Some(point), ..checkpoint }.save(&dir.join("coarse.ckpt")).unwrap();
        Checkpoint::of_model(Stage::Refine, &config, &refine, DType::F16)
            .save(&dir.join("refine.ckpt"))
            .unwrap();
        let photo =
            RgbImage::from_fn(96, 64, |x, y| Rgb([(x * 2) as u8, (y * 3) as u8, ((x + y) % 200) as u8]));
        photo.save(dir.join("photo.png")).unwrap();
        Self { dir }
    }

    /// A file in the folder.
    pub fn path(&self, name: &str) -> PathBuf {
        self.dir.join(name)
    }

    /// Runs `infer` with `args` and the folder's models.
    pub fn infer(&self, args: &[&str]) -> Output {
        Command::new(INFER)
            .args(args)
            .args([
                "--coarse",
                self.path("coarse.ckpt").to_str().unwrap(),
                "--refine",
                self.path("refine.ckpt").to_str().unwrap(),
            ])
            .output()
            .unwrap()
    }
}

impl Drop for Fixture {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

/// Output bytes as text.
pub fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}
