//! Stage by stage the drawing can only get better: fallback ≤ coarse ≤ coarse + refinement ≤
//! fine-tuned, at one budget, with the bundled models.

use std::ops::ControlFlow;
use std::sync::Arc;

use burn::tensor::Device;
use common::decode::load;
use common::psnr;
use image::{Rgb, Rgb32FImage};
use infer::budget::{CoarseShare, Market, Pricing};
use infer::stages::{FallbackDrawing, Proposer, Segmented, Style, draw_coarse, draw_refinement, fitted_path};
use infer::{
    Context, FinetuneOptions, Limit, Models, Origin, Progress, Scene, finetune, finetune_with_progress,
};
use rand::SeedableRng;
use raster::Shape;
use superpixel::{Hierarchy, SegmentOptions, segment};

/// The stages' context: the models' configuration, 16 crops a call.
fn context<'a>(models: &'a Models, device: &'a Device) -> Context<'a> {
    Context { config: &models.config, batch: 16, device }
}

fn images() -> Vec<Rgb32FImage> {
    let root = concat!(env!("CARGO_MANIFEST_DIR"), "/../..");
    let photo = load(std::path::Path::new(&format!("{root}/assets/astronaut.jpg")), 96).unwrap().image;
    let drawing = Rgb32FImage::from_fn(90, 70, |x, y| {
        let inside = ((x as f32 - 40.0).powi(2) + (y as f32 - 30.0).powi(2)).sqrt() < 22.0;
        if inside { Rgb([0.9, 0.7, 0.1]) } else { Rgb([0.1, 0.2 + y as f32 / 200.0, 0.6]) }
    });
    vec![photo, drawing]
}

#[test]
fn no_stage_lowers_the_psnr() {
    let device = Device::flex();
    let models = Models::bundled(true, &device).unwrap();
    let refine = models.refine.as_ref().unwrap();
    let budget = 60;
    for image in images() {
        let image = Arc::new(image);
        let segmentation = Arc::new(
            segment(&image, 20, &SegmentOptions { oversegment: 3.0, ..Default::default() }).unwrap(),
        );
        let score = |scene: &Scene| psnr(&scene.canvas_image(), &image);

        let drawing = FallbackDrawing::new(&image, &segmentation, Style::default());
        let mut fallback = Scene::new(image.clone(), segmentation.clone());
        let no_coarse = CoarseShare { paths: 0, total: 45, market: None };
        draw_coarse(&models.coarse, &context(&models, &device), &mut fallback, drawing.clone(), no_coarse)
            .unwrap();

        // A budget of 3 E_c paths keeps (at most) the 3 that helped most: never more.
        let mut few = Scene::new(image.clone(), segmentation.clone());
        let three = CoarseShare { paths: 3, total: 45, market: None };
        draw_coarse(&models.coarse, &context(&models, &device), &mut few, drawing.clone(), three).unwrap();
        let few_coarse = few.paths().iter().filter(|p| p.origin == Origin::Coarse).count();
        assert!((1..=3).contains(&few_coarse), "{few_coarse} E_c paths for a budget of 3");
        assert!(
            score(&few) >= score(&fallback),
            "3 E_c paths {} < fallback {}",
            score(&few),
            score(&fallback)
        );

        let mut scene = Scene::new(image.clone(), segmentation);
        let coarse_budget = CoarseShare { paths: 24, total: 45, market: None };
        draw_coarse(&models.coarse, &context(&models, &device), &mut scene, drawing, coarse_budget).unwrap();
        let after_coarse = score(&scene);
        assert!(after_coarse >= score(&fallback), "coarse {after_coarse} < fallback {}", score(&fallback));
        assert!(scene.len() <= 45);

        draw_refinement(&context(&models, &device), Proposer::Network(refine), &mut scene, budget, None)
            .unwrap();
        let after_refine = score(&scene);
        assert!(after_refine >= after_coarse, "refinement {after_refine} < coarse {after_coarse}");
        assert!(scene.len() <= budget);
        let refined = scene.paths().iter().filter(|p| p.origin == Origin::Refine).count();
        let coarse_kept = scene.paths().iter().filter(|p| p.origin == Origin::Coarse).count();
        assert!(
            coarse_kept > 0 && refined > 0,
            "the stages kept {coarse_kept} and {refined} paths: nothing was compared"
        );

        let options = FinetuneOptions { limit: Limit::Steps(10), ..FinetuneOptions::default() };
        finetune(&mut scene, &options);
        let after_finetune = score(&scene);
        assert!(after_finetune >= after_refine, "fine-tuning {after_finetune} < refinement {after_refine}");
        assert_eq!(scene.paths().iter().filter(|p| p.origin == Origin::Refine).count(), refined);
    }
}

/// Flat art with anti-aliased curves (random blobs over white), where fine regions leave the
/// most to E_c: what it buys paths on.
fn blobs(seed: u64) -> Rgb32FImage {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let scene = raster::random_scene(&mut rng, 6);
    image::DynamicImage::ImageRgb8(raster::render_exact(&scene, 96, 96, [1.0; 3])).to_rgb32f()
}

/// Bought with regions, E_c's and then E_r's paths never draw worse than the regions they take
/// the place of: the scene is, or beats, the fallback drawing of the whole segmentation (and
/// then the drawing E_c left), the budget holds, paths are bought only where regions were merged
/// away or paths were free, and the canvas is the rendering of the paths; with merges priced
/// either way.
#[test]
fn paths_bought_with_regions_draw_better_than_the_regions() {
    let device = Device::flex();
    let models = Models::bundled(true, &device).unwrap();
    let refine = models.refine.as_ref().unwrap();
    // Fine regions: on these pictures E_c buys a few paths at 161 paths and tens at 241.
    let total = 241;
    for pricing in [Pricing::Flat, Pricing::Drawn] {
        let (mut bought, mut merged_for_refine) = (0, 0);
        for image in [blobs(0), blobs(1), images().remove(0)] {
            let image = Arc::new(image);
            // Merged from SLIC's segments, as a photo is: from their areas of one colour these
            // flat pictures are drawn so nearly exactly that E_r finds nothing to buy.
            let slic = SegmentOptions { flat_areas: false, ..SegmentOptions::ward(30.0) };
            let tree = Hierarchy::new(&image, slic.over_segment(&image, total - 1).unwrap());
            let Segmented { hierarchy, segmentation, fallback: drawing } =
                Segmented::new(&image, tree, total - 1, Style::default());
            let regions = segmentation.regions.len();
            let alone = psnr(
                &Scene::drawn(image.clone(), segmentation.clone(), drawing.placed(), drawing.canvas.clone())
                    .canvas_image(),
                &image,
            );
            let mut scene = Scene::new(image.clone(), segmentation);
            let market = Market { hierarchy: &hierarchy, style: Style::default(), pricing };
            let budget = CoarseShare { paths: 48, total, market: Some(market) };
            draw_coarse(&models.coarse, &context(&models, &device), &mut scene, drawing, budget).unwrap();
            let drawn = psnr(&scene.canvas_image(), &image);
            let coarse = scene.paths().iter().filter(|p| p.origin == Origin::Coarse).count();
            assert!(
                drawn >= alone,
                "{pricing:?}: {drawn} dB with {coarse} E_c paths < {alone} dB for the regions alone"
            );
            assert!(
                scene.len() <= total && coarse <= 48,
                "{pricing:?}: {} paths, {coarse} of E_c",
                scene.len()
            );
            assert!(
                coarse == 0 || scene.segmentation().regions.len() < regions,
                "{pricing:?}: {coarse} E_c paths bought without a merge"
            );
            // The canvas is the drawing of the scene's paths, E_c's among the regions.
            let rendered = raster::render_exact(&scene.scene(), 96, image.height(), [1.0; 3]);
            assert_eq!(scene.canvas_rgb8(), rendered, "the canvas is the rendering of the paths");
            bought += coarse;

            let (before, regions, free) = (drawn, scene.segmentation().regions.len(), total - scene.len());
            let context = context(&models, &device);
            let tally = draw_refinement(&context, Proposer::Network(refine), &mut scene, total, Some(market))
                .unwrap();
            let after = psnr(&scene.canvas_image(), &image);
            let refined = scene.counts().refine;
            assert!(
                after >= before,
                "{pricing:?}: {after} dB with {refined} E_r paths < {before} dB before them"
            );
            assert!(scene.len() <= total, "{pricing:?}: {} paths for a budget of {total}", scene.len());
            assert_eq!(tally.kept, refined);
            let left = scene.segmentation().regions.len();
            assert!(
                refined <= free || left < regions,
                "{pricing:?}: {refined} E_r paths past {free} free without a merge"
            );
            let rendered = raster::render_exact(&scene.scene(), 96, image.height(), [1.0; 3]);
            assert_eq!(scene.canvas_rgb8(), rendered, "the canvas is the rendering of the paths");
            merged_for_refine += regions - left;
        }
        assert!(bought > 0, "{pricing:?}: no image bought an E_c path: the trade was not exercised");
        assert!(
            merged_for_refine > 0,
            "{pricing:?}: E_r bought no path with a region: its trade was not exercised"
        );
    }
}

#[test]
fn fine_tuning_reports_the_psnr_it_reaches() {
    let device = Device::flex();
    let image = Arc::new(images().remove(1));
    let segmentation = Arc::new(segment(&image, 12, &SegmentOptions::default()).unwrap());
    let regions = segmentation.regions.len();
    let mut scene = Scene::new(image.clone(), segmentation.clone());
    let models = Models::bundled(false, &device).unwrap();
    let drawing = FallbackDrawing::new(&image, &segmentation, Style::default());
    let no_coarse = CoarseShare { paths: 0, total: regions + 1, market: None };
    draw_coarse(&models.coarse, &context(&models, &device), &mut scene, drawing, no_coarse).unwrap();
    // Fine-tuning moves paths: a drawing of paths alone (the traced regions, each fitted with
    // one path, as fine-tuning itself starts from them) is what it must improve on.
    let size = image.dimensions();
    let paths: Vec<Shape> = scene
        .scene()
        .iter()
        .map(|shape| match shape {
            Shape::Path(path) => Shape::Path(*path),
            Shape::Outline(outline) => Shape::Path(fitted_path(outline, size).unwrap()),
        })
        .collect();
    scene.set_shapes(&paths);
    let before = psnr(&scene.canvas_image(), &image);

    let mut reports: Vec<Progress> = Vec::new();
    let options = FinetuneOptions { limit: Limit::Steps(20), ..FinetuneOptions::default() };
    let steps = finetune_with_progress(&mut scene, &options, &mut |p| {
        reports.push(*p);
        ControlFlow::Continue(())
    });
    let after = psnr(&scene.canvas_image(), &image);
    let last = reports.last().expect("at least one turn was reported");
    assert_eq!(last.steps, steps);
    assert_eq!(last.total_steps, Some(20));
    assert!(reports.windows(2).all(|w| w[0].steps <= w[1].steps && w[0].seconds <= w[1].seconds));
    let running = reports[reports.len() - 2];
    assert!((running.psnr - after).abs() < 0.3, "running {:.3} dB, drew {after:.3} dB", running.psnr);
    assert!((last.psnr - after).abs() < 0.01, "reported {:.3} dB, drew {after:.3} dB", last.psnr);
    assert!(after > before, "fine-tuning {after:.2} dB did not improve on {before:.2} dB");
}
