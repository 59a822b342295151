//! README's first command: the bundled models vectorize the bundled example image, unaided.

use std::process::Command;

use infer::decode::load;
use infer::metrics::psnr;
use infer::peers::{mean_color_superpixels, render_svg};

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
    let (flat, regions, _) = mean_color_superpixels(&image, 1);
    assert_eq!(regions, 1);
    let (ours, baseline) = (psnr(&drawn, &image), psnr(&flat, &image));
    assert!(ours > baseline, "bundled models: {ours:.2} dB, flat mean colour: {baseline:.2} dB");
    assert_eq!(svg.matches("<path").count(), 200);
    std::fs::remove_dir_all(&dir).unwrap();
}
