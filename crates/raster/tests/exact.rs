//! The soft rasterizer against tiny-skia, and the SVG writer against resvg.

use burn::tensor::Device;
use image::RgbImage;
use rand::SeedableRng;
use raster::{PathBatch, SoftRasterOptions, paint_exact, random_scene, render_exact, render_soft, to_svg};

const SIZE: u32 = 64;

/// PSNR in dB between two equally sized buffers of values in [0, 1].
fn psnr(a: &[f32], b: &[f32]) -> f64 {
    let mse = a.iter().zip(b).map(|(x, y)| ((x - y) as f64).powi(2)).sum::<f64>() / a.len() as f64;
    common::psnr_of_mse(mse)
}

/// Planar `[3, H, W]` values of an RGB image, to compare with a rendered tensor.
fn planar(image: &RgbImage) -> Vec<f32> {
    (0..3).flat_map(|c| image.pixels().map(move |p| p.0[c] as f32 / 255.0)).collect()
}

#[test]
fn soft_render_matches_tiny_skia() {
    let device = Device::flex();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
    let options = SoftRasterOptions { segments_per_curve: 8, ..Default::default() };
    for _ in 0..20 {
        let scene = random_scene(&mut rng, 8);
        let batch = PathBatch::from_scenes(std::slice::from_ref(&scene), &device);
        let soft: Vec<f32> =
            render_soft(&batch, SIZE as usize, SIZE as usize, &options).try_to_vec_as().unwrap();
        let exact = planar(&render_exact(&scene, SIZE, SIZE, [1.0; 3]));
        let db = psnr(&soft, &exact);
        assert!(db >= 28.0, "soft vs exact: {db:.1} dB");
    }
}

#[test]
fn written_svg_renders_like_the_exact_renderer() {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(12);
    for _ in 0..10 {
        let mut scene = random_scene(&mut rng, 8);
        scene[3].alpha = 0.5;
        scene[5].alpha = 0.0;
        let background = [0.9, 0.95, 1.0];
        let svg = to_svg(&scene, SIZE, SIZE, Some(background)).unwrap();
        let tree = resvg::usvg::Tree::from_str(&svg, &resvg::usvg::Options::default()).expect("valid SVG");
        assert_eq!(tree.size().width(), SIZE as f32);
        let mut pixmap = resvg::tiny_skia::Pixmap::new(SIZE, SIZE).unwrap();
        resvg::render(&tree, resvg::tiny_skia::Transform::identity(), &mut pixmap.as_mut());
        let from_svg: Vec<f32> = (0..3)
            .flat_map(|c| pixmap.data().chunks(4).map(move |p| p[c] as f32 / 255.0).collect::<Vec<_>>())
            .collect();
        let exact = planar(&render_exact(&scene, SIZE, SIZE, background));
        let db = psnr(&from_svg, &exact);
        assert!(db >= 40.0, "resvg of the SVG vs render_exact: {db:.1} dB");
    }
}

#[test]
fn painting_a_box_gives_the_pixels_of_the_whole_rendering() {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(13);
    let background = [0.2, 0.9, 0.4];
    for _ in 0..5 {
        let scene = random_scene(&mut rng, 12);
        let whole = render_exact(&scene, SIZE, SIZE, background);
        let (origin, size) = ((9, 20), (30, 17));
        // The box alone, every path placed by its offset from the box's top-left pixel.
        let mut pixmap = resvg::tiny_skia::Pixmap::new(size.0, size.1).unwrap();
        let [r, g, b] = background;
        pixmap.fill(resvg::tiny_skia::Color::from_rgba(r, g, b, 1.0).unwrap());
        for path in &scene {
            paint_exact(&mut pixmap, path, (SIZE, SIZE), origin);
        }
        let window: Vec<f32> =
            (0..3).flat_map(|c| pixmap.data().chunks_exact(4).map(move |px| px[c] as f32 / 255.0)).collect();
        let expected: Vec<f32> = (0..3)
            .flat_map(|c| {
                let whole = &whole;
                (origin.1..origin.1 + size.1).flat_map(move |y| {
                    (origin.0..origin.0 + size.0).map(move |x| whole.get_pixel(x, y).0[c] as f32 / 255.0)
                })
            })
            .collect();
        // tiny-skia anti-aliases an edge in strips that depend on the pixmap's size, so a few
        // edge pixels differ by some levels; everything else is identical.
        let differ = window.iter().zip(&expected).filter(|(a, b)| a != b).count();
        let worst = window.iter().zip(&expected).map(|(a, b)| (a - b).abs()).fold(0.0, f32::max);
        let db = psnr(&window, &expected);
        assert!(
            db >= 40.0 && worst <= 0.1 && differ * 10 < window.len(),
            "{db:.1} dB, {differ} differ, worst {worst}"
        );
    }
}
