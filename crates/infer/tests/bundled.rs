//! README's first command: the bundled models vectorize the bundled example image, unaided, and
//! draw it at least about as well as its own superpixels filled with their mean colour.

use std::process::Command;

use common::decode::load;
use common::psnr;
use image::{Rgb, Rgb32FImage};
use superpixel::{SlicOptions, slic};

/// The SVG rendered by resvg on a transparent canvas: RGB over white, and each pixel's alpha.
fn render(svg: &str, width: u32, height: u32) -> (Rgb32FImage, Vec<u8>) {
    let tree = resvg::usvg::Tree::from_str(svg, &resvg::usvg::Options::default()).unwrap();
    let mut pixmap = resvg::tiny_skia::Pixmap::new(width, height).unwrap();
    let size = tree.size();
    let scale =
        resvg::tiny_skia::Transform::from_scale(width as f32 / size.width(), height as f32 / size.height());
    resvg::render(&tree, scale, &mut pixmap.as_mut());
    let alpha = pixmap.pixels().iter().map(|p| p.alpha()).collect();
    let rgb = Rgb32FImage::from_fn(width, height, |x, y| {
        let p = pixmap.pixel(x, y).unwrap();
        let over_white = |c: u8| (c as f32 + (255 - p.alpha()) as f32) / 255.0;
        Rgb([over_white(p.red()), over_white(p.green()), over_white(p.blue())])
    });
    (rgb, alpha)
}

#[test]
fn bundled_models_draw_the_example_image() {
    let root = concat!(env!("CARGO_MANIFEST_DIR"), "/../..");
    let input = format!("{root}/assets/astronaut.jpg");
    let dir = std::env::temp_dir().join(format!("supersvg-bundled-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let output = dir.join("astronaut.svg");
    let budget = 200;
    let result = Command::new(env!("CARGO_BIN_EXE_infer"))
        .args([&input, "-o", output.to_str().unwrap(), "--paths", &budget.to_string(), "--size", "128"])
        .env_remove("SUPERSVG_MODELS")
        .output()
        .unwrap();
    assert!(result.status.success(), "{}", String::from_utf8_lossy(&result.stderr));

    let image = load(std::path::Path::new(&input), 128).unwrap().image;
    let (width, height) = image.dimensions();
    let svg = std::fs::read_to_string(&output).unwrap();
    let paths = svg.matches("<path").count();
    assert!(paths <= budget && paths > budget / 2, "{paths} paths for a budget of {budget}");

    // Paths alone cover every pixel: no hole, no seam.
    let (drawn, alpha) = render(&svg, width, height);
    let uncovered = alpha.iter().filter(|&&a| a < 255).count();
    assert_eq!(uncovered, 0, "{uncovered} pixels not fully covered");

    // The floor: within a decibel of the pixel-exact superpixel mosaic with as many regions as
    // paths.
    let segmentation = slic(&image, &SlicOptions { n_segments: budget, ..Default::default() }).unwrap();
    let mosaic = Rgb32FImage::from_fn(width, height, |x, y| {
        Rgb(segmentation.regions[segmentation.label(x, y) as usize].mean_color)
    });
    let (ours, floor) = (psnr(&drawn, &image), psnr(&mosaic, &image));
    assert!(ours >= floor - 1.0, "bundled models: {ours:.2} dB, mosaic of {budget} regions: {floor:.2} dB");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// What `cargo install` gives: the program alone in a folder of its own, run from another,
/// with no models folder anywhere, draws what the checkpoint files in models/ draw.
#[test]
fn an_installed_program_carries_its_models() {
    let root = concat!(env!("CARGO_MANIFEST_DIR"), "/../..");
    let input = format!("{root}/assets/astronaut.jpg");
    let dir = std::env::temp_dir().join(format!("supersvg-installed-{}", std::process::id()));
    let (bin, elsewhere) = (dir.join("bin"), dir.join("work"));
    std::fs::create_dir_all(&bin).unwrap();
    std::fs::create_dir_all(&elsewhere).unwrap();
    let installed = bin.join("infer");
    std::fs::copy(env!("CARGO_BIN_EXE_infer"), &installed).unwrap();
    let draw = |program: &std::path::Path, extra: &[String], out: &str| {
        let result = Command::new(program)
            .args([&input, "-o", out, "--paths", "60", "--size", "96"])
            .args(extra)
            .current_dir(&elsewhere)
            .env_remove("SUPERSVG_MODELS")
            .output()
            .unwrap();
        assert!(result.status.success(), "{}", String::from_utf8_lossy(&result.stderr));
        String::from_utf8_lossy(&result.stderr).into_owned()
    };
    let said = draw(&installed, &[], "installed.svg");
    assert!(said.contains("coarse built-in coarse.ckpt (weights "), "{said}");
    let files = ["--coarse", "coarse.ckpt", "--refine", "refine.ckpt", "--mover", "mover.ckpt"]
        .map(|a| if a.ends_with(".ckpt") { format!("{root}/models/{a}") } else { a.to_string() });
    draw(std::path::Path::new(env!("CARGO_BIN_EXE_infer")), &files, "files.svg");
    let read = |name: &str| std::fs::read(elsewhere.join(name)).unwrap();
    assert!(read("installed.svg") == read("files.svg"), "the built-in models draw otherwise than models/");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The bundled mover moves the example photo's outlines onto its edges: `infer` names it, and
/// it draws the photo better than `--moves off` in no more bytes.
#[test]
fn the_bundled_mover_draws_the_example_better_in_no_more_bytes() {
    let root = concat!(env!("CARGO_MANIFEST_DIR"), "/../..");
    let input = format!("{root}/assets/astronaut.jpg");
    let dir = std::env::temp_dir().join(format!("supersvg-mover-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let draw = |moves: &str| {
        let metrics = dir.join(format!("{moves}.json"));
        let result = Command::new(env!("CARGO_BIN_EXE_infer"))
            .args([&input, "-o", dir.join(format!("{moves}.svg")).to_str().unwrap(), "--paths", "100"])
            .args(["--size", "128", "--moves", moves, "--metrics", metrics.to_str().unwrap()])
            .env_remove("SUPERSVG_MODELS")
            .output()
            .unwrap();
        assert!(result.status.success(), "{}", String::from_utf8_lossy(&result.stderr));
        let report: serde_json::Value = serde_json::from_slice(&std::fs::read(metrics).unwrap()).unwrap();
        (report, String::from_utf8_lossy(&result.stderr).into_owned())
    };
    let ((moved, said), (drawn, _)) = (draw("auto"), draw("off"));
    assert!(said.contains("mover built-in mover.ckpt (weights "), "{said}");
    let (gain, kept) =
        (moved["moves"]["gain_db"].as_f64().unwrap(), moved["moves"]["kept"].as_bool().unwrap());
    let psnr = |report: &serde_json::Value| report["psnr"].as_f64().unwrap();
    let bytes = |report: &serde_json::Value| report["svg_bytes"].as_u64().unwrap();
    assert!(kept && gain >= 0.4, "{}", moved["moves"]);
    // The report measures the files, the tally the drawings: they agree to the rounding.
    assert!((psnr(&moved) - psnr(&drawn) - gain).abs() < 0.05 && drawn["moves"].is_null());
    assert!(bytes(&moved) <= bytes(&drawn), "{} bytes moved, {} as drawn", bytes(&moved), bytes(&drawn));
    std::fs::remove_dir_all(&dir).unwrap();
}
