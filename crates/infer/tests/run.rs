//! `infer::run` with small untrained models (and the bundled mover): budgets, coverage,
//! determinism, the automatic budget, where the mover runs, and errors a caller can make. (What only the `infer` program does — arguments,
//! files, streams — is in cli.rs.)

use burn::tensor::Device;
use common::Loaded;
use image::{Rgb, Rgb32FImage};
use infer::{
    AutoRule, BUILT_IN_MOVER, Fills, FinetuneOptions, InvalidJob, Job, Limit, ModelSource, Models, Moves,
    Network, PathBudget, Split, VectorizeError, run,
};
use model::OperatingPoint;

mod support;

/// Tiny networks of a fixed seed, with or without E_r, at the default operating point.
fn models(refine: bool) -> Models {
    let (config, coarse, e_r) = support::tiny_models(&Device::flex());
    Models {
        coarse: Network::in_memory(coarse, "tiny E_c"),
        refine: refine.then(|| Network::in_memory(e_r, "tiny E_r")),
        mover: None,
        optimizer: None,
        config,
        operating_point: OperatingPoint::default(),
    }
}

/// The job a run refused as invalid, if that is why it failed.
fn invalid<T>(result: Result<T, VectorizeError>) -> Option<InvalidJob> {
    match result {
        Err(VectorizeError::Invalid(invalid)) => Some(invalid),
        _ => None,
    }
}

fn photo() -> Loaded {
    Loaded::from_image(Rgb32FImage::from_fn(96, 64, |x, y| {
        Rgb([x as f32 / 48.0 % 1.0, y as f32 * 3.0 / 255.0, ((x + y) % 200) as f32 / 255.0])
    }))
}

fn job(paths: usize) -> Job {
    Job { paths: PathBudget::Count(paths), ..Job::default() }
}

/// How many pixels an SVG leaves less than fully covered, rendered on a transparent canvas.
fn uncovered(svg: &str, width: u32, height: u32) -> usize {
    let tree = resvg::usvg::Tree::from_str(svg, &resvg::usvg::Options::default()).expect("valid SVG");
    let mut pixmap = resvg::tiny_skia::Pixmap::new(width, height).unwrap();
    resvg::render(&tree, resvg::tiny_skia::Transform::identity(), &mut pixmap.as_mut());
    pixmap.pixels().iter().filter(|p| p.alpha() < 255).count()
}

#[test]
fn stays_within_the_budget_and_reports_what_it_drew() {
    let (models, image, device) = (models(true), photo(), Device::flex());
    let mut proposed = 0;
    for budget in [2usize, 3, 40, 100] {
        let outcome = run(&models, &image, &job(budget), &device).unwrap();
        let (report, svg) = (&outcome.report, &outcome.svg);
        let paths = svg.matches("<path").count();
        // The default operating point gives every path but the background a region of its own.
        assert!(paths <= budget && paths * 10 >= budget * 9, "{paths} paths for a budget of {budget}");
        assert_eq!((report.paths, report.paths_by_stage.total(), report.budget), (paths, paths, budget));
        assert_eq!(report.paths_by_stage.background, 1);
        assert_eq!((report.svg_bytes, report.width, report.working_width), (svg.len(), 96, 96));
        assert!(svg.contains("viewBox=\"0 0 96 64\""));
        // The report measures the drawing as the SVG writes it.
        let drawn = common::psnr(&outcome.written.canvas_image(), &image.image);
        assert!((report.psnr - drawn).abs() < 1e-9 && report.psnr > 10.0, "{} vs {drawn}", report.psnr);
        let seconds = report.seconds;
        let parts = seconds.decode
            + seconds.superpixels
            + seconds.coarse
            + seconds.refine
            + seconds.moves
            + seconds.export;
        assert!((seconds.total - parts).abs() < 1e-9 && seconds.finetune.is_none());
        // The networks' passes are part of the coarse and refinement stages' time, and take
        // time where E_r proposed (where the drawing leaves it no region, it is not asked).
        assert!(seconds.networks <= seconds.coarse + seconds.refine, "{seconds:?}");
        assert_eq!(
            seconds.networks > 0.0,
            report.refinement.proposed > 0,
            "{seconds:?} {:?}",
            report.refinement
        );
        proposed += report.refinement.proposed;
    }
    assert!(proposed > 0, "E_r proposed nothing at any budget");
}

#[test]
fn paths_cover_every_pixel_at_any_budget_and_region_count() {
    let image = photo();
    let device = Device::flex();
    let cases = [(2, None), (3, Some(1)), (40, Some(39)), (100, None), (400, Some(399)), (60, Some(7))];
    for refine in [true, false] {
        let models = models(refine);
        for (paths, regions) in cases {
            let outcome = run(&models, &image, &Job { regions, ..job(paths) }, &device).unwrap();
            assert!(outcome.report.paths <= paths, "{paths} / {regions:?}");
            assert!(!outcome.svg.contains("<rect"), "coverage must come from paths alone");
            assert_eq!(
                uncovered(&outcome.svg, 96, 64),
                0,
                "{paths} paths, {regions:?} regions, E_r {refine}"
            );
        }
    }
}

/// `--operating-point paper`: E_c's paths on budget/64 SLIC regions with no fallback path, E_r
/// appended, within the budget and over the background path, so no pixel is left uncovered;
/// a region count or an automatic budget is refused.
#[test]
fn the_papers_inference_draws_without_fallbacks_within_the_budget() {
    let (models, image, device) = (models(true), photo(), Device::flex());
    let paper = |paths| Job { operating_point: Split::Paper, ..job(paths) };
    for budget in [2, 40, 200] {
        let outcome = run(&models, &image, &paper(budget), &device).unwrap();
        let (report, stages) = (&outcome.report, outcome.report.paths_by_stage);
        assert_eq!((stages.background, stages.fallback), (1, 0), "{budget}: {stages:?}");
        assert!(report.paths <= budget, "{budget}: {} paths", report.paths);
        assert!(stages.coarse + stages.refine > 0, "{budget}: the networks drew nothing");
        assert_eq!(report.operating_point, Split::Paper);
        assert_eq!(report.refinement.kept, stages.refine, "E_r's paths are all appended");
        assert_eq!(uncovered(&outcome.svg, 96, 64), 0, "{budget}");
        if budget < 64 {
            assert_eq!(report.regions, 1, "fewer than 64 paths: one region");
        }
        if budget == 200 {
            assert!(stages.refine > 0, "E_r fills what E_c leaves: {stages:?}");
        }
    }
    for refused in [
        Job { regions: Some(5), ..paper(40) },
        Job { paths: PathBudget::Auto(AutoRule::default()), ..paper(40) },
    ] {
        assert_eq!(invalid(run(&models, &image, &refused, &device)), Some(InvalidJob::PaperNeedsCount));
    }
}

/// The report says what E_r did: every refinement path is one it kept, of the proposals it
/// tried, and together they raised the PSNR by what the report says.
#[test]
fn the_report_tallies_what_e_r_proposed_and_kept() {
    let (both, image, device) = (models(true), photo(), Device::flex());
    let point = OperatingPoint { coarse_share: 0.0, refine_share: 0.5 };
    let split = Job { operating_point: Split::Point(point), ..job(100) };
    let outcome = run(&both, &image, &split, &device).unwrap();
    let (tally, stages) = (outcome.report.refinement, outcome.report.paths_by_stage);
    assert_eq!(tally.kept, stages.refine);
    assert!(tally.kept > 0 && tally.proposed >= tally.kept, "{tally:?}");
    // The drawing E_r was handed: the same regions, no E_r.
    let regions = Some(outcome.report.regions);
    let before = run(&models(false), &image, &Job { regions, ..split.clone() }, &device).unwrap().report;
    assert_eq!(before.paths_by_stage.refine, 0);
    // The report measures the files (the shapes as written), the tally the drawing as the stage
    // left it: they agree to the rounding.
    let gained = outcome.report.psnr - before.psnr;
    assert!(gained > 0.0 && (tally.gain_db - gained).abs() < 0.05, "{tally:?}: {gained} dB");
    assert_eq!(run(&models(false), &image, &split, &device).unwrap().report.refinement, Default::default());
}

#[test]
fn runs_are_deterministic() {
    let (models, image, device) = (models(true), photo(), Device::flex());
    let first = run(&models, &image, &job(30), &device).unwrap();
    let second = run(&models, &image, &job(30), &device).unwrap();
    assert_eq!(first.svg, second.svg);
}

#[test]
fn an_automatic_budget_gives_flat_art_few_paths_and_takes_no_region_count() {
    let (models, device) = (models(true), Device::flex());
    let flat = Loaded::from_image(Rgb32FImage::from_fn(80, 60, |x, _| {
        if x < 40 { Rgb([0.8, 0.1, 0.1]) } else { Rgb([0.1, 0.15, 0.85]) }
    }));
    let auto = Job { paths: PathBudget::Auto(AutoRule::default()), ..Job::default() };
    let outcome = run(&models, &flat, &auto, &device).unwrap();
    // Two flat halves are drawn exactly by two regions: the first rung of the ladder.
    assert_eq!(outcome.report.budget, 8, "two flat halves got a budget of {}", outcome.report.budget);
    assert!(outcome.report.auto_budget && outcome.report.paths <= 8);
    let refused = invalid(run(&models, &flat, &Job { regions: Some(5), ..auto }, &device));
    assert_eq!(refused, Some(InvalidJob::RegionsWithAuto));
}

#[test]
fn budgets_and_region_counts_out_of_range_are_errors() {
    let (models, image, device) = (models(false), photo(), Device::flex());
    for paths in [0, 1, infer::MAX_PATHS + 1] {
        assert_eq!(invalid(run(&models, &image, &job(paths), &device)), Some(InvalidJob::Budget(paths)));
    }
    for regions in [0, 40, 41] {
        let err = invalid(run(&models, &image, &Job { regions: Some(regions), ..job(40) }, &device));
        assert_eq!(err, Some(InvalidJob::Regions { regions, paths: 40 }));
    }
    // More regions than the image has room for: drawn with fewer, and said.
    let tiny = Loaded::from_image(Rgb32FImage::from_pixel(8, 8, Rgb([0.3, 0.3, 0.3])));
    let outcome = run(&models, &tiny, &Job { regions: Some(30), ..job(40) }, &device).unwrap();
    assert!(outcome.report.regions <= 4, "{} regions on 64 pixels", outcome.report.regions);
    let said = outcome.warnings.iter().map(ToString::to_string).collect::<Vec<_>>().join("; ");
    assert!(said.contains("30 regions lowered to 4"), "{said}");
}

#[test]
fn no_fine_tuning_step_is_no_fine_tuning() {
    use infer::{FinetuneOptions, Limit};
    let (models, image, device) = (models(true), photo(), Device::flex());
    // With the fills given: by default F fills flat and B with ramps.
    let plain_job = Job { fills: Some(infer::Fills::Auto), ..job(30) };
    let plain = run(&models, &image, &plain_job, &device).unwrap();
    for budget in [Limit::Steps(0), Limit::Seconds(0.0)] {
        let finetune = Some(FinetuneOptions { limit: budget, ..FinetuneOptions::default() });
        let tuned = run(&models, &image, &Job { finetune, ..plain_job.clone() }, &device).unwrap();
        assert!(tuned.svg == plain.svg, "{budget:?} changed the drawing");
        assert_eq!(tuned.report.finetune_steps, Some(0));
    }
}

#[test]
fn a_flat_picture_is_one_path_and_says_so() {
    let (models, device) = (models(true), Device::flex());
    let flat = Loaded::from_image(Rgb32FImage::from_pixel(80, 60, Rgb([0.1, 0.5, 0.8])));
    let outcome = run(&models, &flat, &job(500), &device).unwrap();
    assert_eq!(outcome.report.paths, 1, "{:?}", outcome.report.paths_by_stage);
    let said: Vec<String> = outcome.warnings.iter().map(ToString::to_string).collect();
    assert!(said.iter().any(|w| w.starts_with("1 of 500 paths drawn")), "{said:?}");
}

#[test]
fn curves_cover_every_pixel_and_a_looser_tolerance_writes_fewer_bytes() {
    let (models, image, device) = (models(false), photo(), Device::flex());
    let mut bytes = Vec::new();
    for tolerance in [Some(0.0), Some(0.5), Some(2.0)] {
        for budget in [12usize, 60, 200] {
            let outcome = run(&models, &image, &Job { tolerance, ..job(budget) }, &device).unwrap();
            assert_eq!(uncovered(&outcome.svg, 96, 64), 0, "{tolerance:?} at {budget} paths");
            assert!(outcome.svg.contains('c') || tolerance == Some(0.0), "curves at {tolerance:?}");
            if budget == 200 {
                bytes.push(outcome.report.svg_bytes);
            }
        }
    }
    assert!(bytes[2] < bytes[1] && bytes[1] < bytes[0], "bytes at tolerance 0, 0.5, 2: {bytes:?}");
}

/// The exact optimizer proposes in E_r's place, with or without E_r loaded: it keeps the share
/// of the budget the split reserves for refinement, keeps paths there, each lowering the error,
/// and draws better than the (untrained) E_r given the same share.
#[test]
fn the_optimizer_refines_in_place_of_e_r() {
    use infer::Refiner;
    let (image, device) = (photo(), Device::flex());
    let point = OperatingPoint { coarse_share: 0.0, refine_share: 0.3 };
    let split = |refiner| Job { operating_point: Split::Point(point), refiner, ..job(40) };
    let optimizer = Refiner::Optimizer { steps: 30 };
    let e_r = run(&models(true), &image, &split(Refiner::Network), &device).unwrap().report;
    let with_e_r = run(&models(true), &image, &split(optimizer), &device).unwrap().report;
    let optimized = run(&models(false), &image, &split(optimizer), &device).unwrap().report;
    assert_eq!((optimized.psnr, optimized.paths), (with_e_r.psnr, with_e_r.paths), "E_r plays no part");
    assert_eq!(optimized.operating_point, Split::Point(point));
    assert!(optimized.paths_by_stage.refine > 0 && optimized.paths <= 40, "{:?}", optimized.paths_by_stage);
    assert!(optimized.refinement.gain_db > 0.0 && optimized.psnr > e_r.psnr, "{optimized:?} against {e_r:?}");
}

/// Tiny E_c and E_r beside the bundled mover.
fn with_mover() -> Models {
    let device = Device::flex();
    models(true).with_mover(&ModelSource::BuiltIn(&BUILT_IN_MOVER), &device).unwrap()
}

/// The mover runs where the job says: by default where B fills with ramps (not with flat
/// fills, nor on flat art), always with `Moves::On`, never with `Moves::Off` or without a
/// mover; where it runs, its moves are kept only if the drawing is better for them, and its
/// time is part of the total.
#[test]
fn the_mover_runs_where_the_job_says_and_keeps_only_a_better_drawing() {
    let (moving, image, device) = (with_mover(), photo(), Device::flex());
    let report = |job: Job, models: &Models| run(models, &image, &job, &device).unwrap().report;
    let off = report(Job { moves: Moves::Off, ..job(100) }, &moving);
    assert_eq!(off.moves, None);
    assert_eq!(report(job(100), &models(true)).psnr, off.psnr, "no mover, no moves");
    let flat = report(Job { fills: Some(Fills::Flat), ..job(100) }, &moving);
    assert_eq!(flat.moves, None, "flat fills are left as drawn by default");
    for job in [job(100), Job { fills: Some(Fills::Flat), moves: Moves::On, ..job(100) }] {
        let moved = report(job.clone(), &moving);
        let tally = moved.moves.expect("the mover ran");
        let before = report(Job { moves: Moves::Off, ..job }, &moving);
        assert!(tally.points > 0 && tally.network_seconds > 0.0, "{tally:?}");
        assert!(
            moved.seconds.moves >= tally.network_seconds && moved.seconds.networks >= tally.network_seconds
        );
        match tally.kept {
            // The report measures the files, the tally the drawings: they agree to the rounding.
            true => assert!((moved.psnr - before.psnr - tally.gain_db).abs() < 0.05, "{tally:?}"),
            false => {
                assert_eq!((moved.psnr, moved.svg_bytes, tally.gain_db), (before.psnr, before.svg_bytes, 0.0))
            }
        }
    }
}

/// Two flat halves that B draws exactly: there is nothing to gain, so whatever the mover
/// predicts, the drawing stays as B drew it, to the byte.
#[test]
fn the_mover_leaves_an_exact_drawing_as_it_was() {
    let (models, device) = (with_mover(), Device::flex());
    let halves = Loaded::from_image(Rgb32FImage::from_fn(64, 48, |x, _| {
        if x < 29 { Rgb([0.9, 0.2, 0.1]) } else { Rgb([0.1, 0.3, 0.8]) }
    }));
    let draw = |moves| run(&models, &halves, &Job { moves, ..job(8) }, &device).unwrap();
    let (moved, drawn) = (draw(Moves::On), draw(Moves::Off));
    let tally = moved.report.moves.expect("the mover ran");
    assert!(!tally.kept && tally.points > 0, "{tally:?}");
    assert_eq!(moved.svg, drawn.svg);
}

/// SuperSVG-F never draws worse than B with the same job: on random jobs (budgets, fills,
/// moves, decimals, steps), an image drawn with F has at most the error of the same job
/// without F, measured on what each file shows.
#[test]
fn f_never_draws_worse_than_b() {
    use rand::{Rng, SeedableRng};
    let device = Device::flex();
    let models = with_mover();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(71);
    let flat_art = Loaded::from_image(Rgb32FImage::from_fn(80, 64, |x, y| {
        let inside = (x as f32 - 30.0).hypot(y as f32 - 30.0) < 18.0;
        if inside {
            Rgb([0.9, 0.2, 0.1])
        } else if x > 60 {
            Rgb([0.1, 0.3, 0.8])
        } else {
            Rgb([0.95, 0.9, 0.6])
        }
    }));
    for round in 0..8 {
        let image = if round % 2 == 0 { photo() } else { flat_art.clone() };
        let paths = match rng.random_range(0..3) {
            0 => PathBudget::Auto(AutoRule::default()),
            _ => PathBudget::Count(rng.random_range(4..120)),
        };
        let fills = [None, Some(Fills::Flat), Some(Fills::Linear), Some(Fills::Auto)][rng.random_range(0..4)];
        let moves = [Moves::Auto, Moves::On, Moves::Off][rng.random_range(0..3)];
        let decimals = rng.random_range(0..4);
        let b = Job {
            paths,
            fills,
            moves,
            svg: raster::SvgOptions { decimals, ..Default::default() },
            ..Job::default()
        };
        let limit = Limit::Steps(rng.random_range(1..40));
        let f = Job { finetune: Some(FinetuneOptions { limit, ..FinetuneOptions::default() }), ..b.clone() };
        let (b_error, f_error) = (
            run(&models, &image, &b, &device).unwrap().report.mse,
            run(&models, &image, &f, &device).unwrap().report.mse,
        );
        assert!(f_error <= b_error, "round {round}: F {f_error} against B {b_error} ({f:?})");
    }
}
