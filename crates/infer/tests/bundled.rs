//! README's first command: the bundled models vectorize the bundled example image, unaided.

use std::process::Command;

use infer::decode::load;
use infer::metrics::psnr;
use infer::peers::render_svg;

#[test]
fn bundled_models_draw_the_example_image() {
    let root = concat!(env!("CARGO_MANIFEST_DIR"), "/../..");
    let input = format!("{root}/assets/astronaut.jpg");
    let dir = std::env::temp_dir().join(format!("supersvg-bundled-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let output = dir.join("astronaut.svg");
    let result = Command::new(env!("CARGO_BIN_EXE_infer"))
        .args([&input, "-o", output.to_str().unwrap(), "--paths", "200", "--size", "128"])
        .env_remove("SUPERSVG_MODELS")
        .output()
        .unwrap();
    assert!(result.status.success(), "{}", String::from_utf8_lossy(&result.stderr));

    // The drawing must resemble the photo better than its best single flat colour does.
    let image = load(std::path::Path::new(&input), 128).unwrap().image;
    let (width, height) = image.dimensions();
    let svg = std::fs::read_to_string(&output).unwrap();
    let drawn = render_svg(&svg, width, height).unwrap();
    let mut mean = [0.0f64; 3];
    for pixel in image.pixels() {
        for (sum, value) in mean.iter_mut().zip(pixel.0) {
            *sum += f64::from(value) / f64::from(width * height);
        }
    }
    let flat = image::Rgb32FImage::from_pixel(width, height, image::Rgb(mean.map(|v| v as f32)));
    let (ours, baseline) = (psnr(&drawn, &image), psnr(&flat, &image));
    assert!(ours > baseline, "bundled models: {ours:.2} dB, flat mean colour: {baseline:.2} dB");
    assert_eq!(svg.matches("<path").count(), 200);
    std::fs::remove_dir_all(&dir).unwrap();
}
