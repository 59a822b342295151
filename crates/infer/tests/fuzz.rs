//! Fuzz-style robustness: corrupted image files and wild path parameters never panic.

use common::decode::load;
use image::{Rgb, RgbImage};
use rand::{Rng, SeedableRng};
use raster::{Filled, Path, SvgError, to_svg};

#[test]
fn corrupted_image_bytes_give_an_image_or_an_error() {
    let dir = std::env::temp_dir().join(format!("supersvg-fuzz-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let picture = RgbImage::from_fn(37, 23, |x, y| Rgb([(x * 7) as u8, (y * 11) as u8, (x * y) as u8]));
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(17);
    let (mut decoded, mut refused) = (0, 0);
    for format in ["png", "jpg", "bmp", "gif", "webp", "tiff"] {
        let clean = dir.join(format!("clean.{format}"));
        picture.save(&clean).unwrap();
        let bytes = std::fs::read(&clean).unwrap();
        for round in 0..40 {
            let mut broken = bytes.clone();
            match round % 3 {
                0 => broken.truncate(rng.random_range(0..bytes.len())),
                1 => (0..rng.random_range(1..8)).for_each(|_| {
                    let i = rng.random_range(0..broken.len());
                    broken[i] = rng.random();
                }),
                _ => {
                    let i = rng.random_range(0..broken.len());
                    broken.splice(i..i, (0..rng.random_range(1..64)).map(|_| rng.random::<u8>()));
                }
            }
            let file = dir.join(format!("broken.{format}"));
            std::fs::write(&file, &broken).unwrap();
            match load(&file, 64) {
                Ok(loaded) => {
                    decoded += 1;
                    assert!(loaded.image.width() >= 1 && loaded.image.height() >= 1);
                    assert!(loaded.image.pixels().all(|p| p.0.iter().all(|c| c.is_finite())));
                }
                Err(err) => {
                    refused += 1;
                    assert_eq!(err.input, file.display().to_string(), "the error names the file: {err}");
                }
            }
        }
    }
    std::fs::remove_dir_all(&dir).unwrap();
    // Both outcomes were exercised: damage some decoders tolerate, and damage refused.
    assert!(decoded >= 20 && refused >= 20, "{decoded} decoded, {refused} refused of 240");
}

#[test]
fn wild_path_parameters_give_valid_svg_or_an_error() {
    let specials =
        [f32::NAN, f32::INFINITY, f32::NEG_INFINITY, f32::MAX, -f32::MAX, 1e30, -1e-30, 0.0, 2.5, -7.0];
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(18);
    let pick = |rng: &mut rand_chacha::ChaCha8Rng| {
        if rng.random_bool(0.3) {
            specials[rng.random_range(0..specials.len())]
        } else {
            rng.random_range(-2.0..3.0)
        }
    };
    let mut valid = 0;
    for _ in 0..300 {
        let paths: Vec<Path> = (0..rng.random_range(0..6))
            .map(|_| Path {
                points: std::array::from_fn(|_| [pick(&mut rng), pick(&mut rng)]),
                color: std::array::from_fn(|_| pick(&mut rng)),
                alpha: pick(&mut rng),
            })
            .collect();
        let (width, height) = (rng.random_range(0..50), rng.random_range(0..50));
        let broken = paths.iter().position(|path| !path.is_finite());
        match to_svg(&paths, width, height, Some([pick(&mut rng); 3])) {
            Ok(svg) => {
                resvg::usvg::Tree::from_str(&svg, &resvg::usvg::Options::default()).expect("the SVG parses");
                assert!(
                    width > 0 && height > 0 && broken.is_none(),
                    "{width}×{height}, path {broken:?} broken"
                );
                valid += 1;
            }
            // Refused for the first reason there is: an empty canvas, then the first broken path.
            Err(SvgError::EmptyCanvas { .. }) => assert!(width == 0 || height == 0),
            Err(SvgError::NonFinite { index }) => assert_eq!(Some(index), broken),
        }
    }
    assert!(valid > 10, "only {valid} documents were written");
}
