//! `eval` refuses flags it cannot honour before any work, with the flag's name, and never hangs.

use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

const EVAL: &str = env!("CARGO_BIN_EXE_eval");

#[test]
fn wild_flag_values_are_refused_by_name_and_never_hang() {
    let dir = std::env::temp_dir().join(format!("supersvg-eval-flags-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    image::RgbImage::from_pixel(20, 10, image::Rgb([10, 200, 30])).save(dir.join("a.png")).unwrap();
    let folder = dir.to_str().unwrap();
    let out = dir.join("report.md");
    // (flag and value, what stderr must name)
    let cases: [(&[&str], &str); 17] = [
        (&["--paths", "0"], "--paths"),
        (&["--paths", "1"], "--paths"),
        (&["--paths", "1000000"], "--paths"),
        (&["--paths", "-5"], "--paths"),
        (&["--paths", "NaN"], "--paths"),
        (&["--finetune-secs", "NaN"], "--finetune-secs"),
        (&["--finetune-secs", "inf"], "--finetune-secs"),
        (&["--finetune-secs=-1"], "--finetune-secs"),
        (&["--size", "0"], "--size"),
        (&["--size", "99999999"], "--size"),
        (&["--peers", "foo"], "foo"),
        (&["--limit", "x"], "--limit"),
        (&["--sweep", "1"], "--sweep"),
        (&["--sweep", "64,x"], "--sweep"),
        (&["--operating-point", "paper"], "--peers paper"),
        (&["--operating-point", "0.9,0.2"], "--operating-point"),
        (&["--fills", "radial"], "--fills"),
    ];
    for (flags, name) in cases {
        let mut child = Command::new(EVAL)
            .arg(folder)
            .args(["--out", out.to_str().unwrap()])
            .args(flags)
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let started = Instant::now();
        while child.try_wait().unwrap().is_none() {
            if started.elapsed() > Duration::from_secs(30) {
                child.kill().unwrap();
                panic!("{flags:?} still running after 30 s");
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        let result = child.wait_with_output().unwrap();
        let stderr = String::from_utf8_lossy(&result.stderr);
        assert!(
            matches!(result.status.code(), Some(1 | 2)),
            "{flags:?}: {:?} {stderr}",
            result.status.code()
        );
        assert!(stderr.contains(name), "{flags:?}: {stderr:?} does not name {name}");
        assert!(!out.exists(), "{flags:?} wrote a report");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A report whose folder does not exist is refused before any image is drawn, naming it.
#[test]
fn a_report_that_cannot_be_written_is_refused_first() {
    let dir = std::env::temp_dir().join(format!("supersvg-eval-nofolder-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    image::RgbImage::from_pixel(20, 10, image::Rgb([10, 200, 30])).save(dir.join("a.png")).unwrap();
    let out = dir.join("missing/report.md");
    let result =
        Command::new(EVAL).arg(&dir).args(["--out", out.to_str().unwrap(), "--peers", ""]).output().unwrap();
    let stderr = String::from_utf8_lossy(&result.stderr);
    assert_eq!(result.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("report.md: the folder") && stderr.contains("does not exist"), "{stderr}");
    assert!(!stderr.contains("[1/1]"), "an image was drawn first: {stderr}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The report compares sizes as well as quality: an SVG KB column (a dash for the pixel-exact
/// mosaic, which is no SVG), a row without E_r, and a section where each method picks its own
/// budget, SuperSVG-B with `--paths auto`.
#[test]
fn report_has_svg_sizes_and_the_auto_budget() {
    let dir = std::env::temp_dir().join(format!("supersvg-eval-report-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let picture = image::RgbImage::from_fn(48, 32, |x, y| image::Rgb([(x * 5) as u8, (y * 7) as u8, 90]));
    picture.save(dir.join("a.png")).unwrap();
    let out = dir.join("report.md");
    let result = Command::new(EVAL)
        .arg(&dir)
        .args([
            "--out",
            out.to_str().unwrap(),
            "--paths",
            "16",
            "--size",
            "48",
            "--peers",
            "slic,no-refine,paper,optimizer",
        ])
        .output()
        .unwrap();
    assert!(result.status.success(), "{}", String::from_utf8_lossy(&result.stderr));
    let report = std::fs::read_to_string(&out).unwrap();
    assert!(report.contains("| method | shapes | SVG KB | PSNR (dB)"), "{report}");
    let row = |method: &str| {
        let line = report.lines().find(|l| l.starts_with(&format!("| {method} |"))).unwrap_or_else(|| {
            panic!("no row for {method} in {report}");
        });
        line.split('|').map(str::trim).nth(3).unwrap().to_string()
    };
    assert!(row("SuperSVG-B (ours)").parse::<f64>().unwrap() > 0.0, "{report}");
    assert!(row("SuperSVG-B (ours), --paths auto").parse::<f64>().unwrap() > 0.0, "{report}");
    assert!(
        row("SuperSVG-B without E_r and the mover (--no-refine)").parse::<f64>().unwrap() > 0.0,
        "{report}"
    );
    let paper = "SuperSVG-B, the paper's inference (--operating-point paper)";
    assert!(row(paper).parse::<f64>().unwrap() > 0.0, "{report}");
    // The optimizer's paths are kept only where they lower the error: never below the drawing
    // without E_r (up to resvg's rendering of the same paths).
    let optimizer: f64 =
        row("SuperSVG-B, the exact optimizer in E_r's place (--refiner optimizer)").parse().unwrap();
    let no_refine: f64 = row("SuperSVG-B without E_r and the mover (--no-refine)").parse().unwrap();
    assert!(optimizer >= no_refine - 0.05, "{optimizer} against {no_refine}: {report}");
    assert_eq!(row("SLIC regions, mean colour"), "—", "{report}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// eval draws SuperSVG through the call `infer` makes: the SVGs it measures are, byte for byte,
/// the files `infer` writes with the same settings (the `infer` program writes what
/// `infer::run` returns; crates/infer/tests/cli.rs checks that side).
#[test]
fn svgs_are_what_infer_writes() {
    let dir = std::env::temp_dir().join(format!("supersvg-eval-svgs-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let picture = image::RgbImage::from_fn(60, 40, |x, y| image::Rgb([(x * 4) as u8, (y * 6) as u8, 120]));
    picture.save(dir.join("a.png")).unwrap();
    // Beside the folder, so that one run's report is not read as an image by the next.
    let written_to = dir.with_extension("out");
    let _ = std::fs::remove_dir_all(&written_to);
    std::fs::create_dir_all(&written_to).unwrap();
    let (out, svgs) = (written_to.join("report.md"), written_to.join("svgs"));
    let device = burn::tensor::Device::flex();
    let models = eval::load_models(None, None, None, &device).unwrap();
    let image = common::decode::load(&dir.join("a.png"), 48).unwrap();
    // infer's default fills, and the ones `--fills` names.
    for (flags, fills) in [(&[][..], None), (&["--fills", "linear"][..], Some(infer::Fills::Linear))] {
        let result = Command::new(EVAL)
            .arg(&dir)
            .args(["--out", out.to_str().unwrap(), "--svgs", svgs.to_str().unwrap()])
            .args(["--paths", "24", "--size", "48", "--peers", ""])
            .args(flags)
            .env_remove("SUPERSVG_MODELS")
            .output()
            .unwrap();
        assert!(result.status.success(), "{}", String::from_utf8_lossy(&result.stderr));
        let budgets = [
            ("a-b-24.svg", infer::PathBudget::Count(24)),
            ("a-auto.svg", infer::PathBudget::Auto(infer::AutoRule::default())),
        ];
        for (file, paths) in budgets {
            let job = infer::Job { paths, fills, ..infer::Job::default() };
            let svg = infer::run(&models, &image, &job, &device).unwrap().svg;
            let written = std::fs::read_to_string(svgs.join(file)).unwrap();
            assert!(written == svg, "{file} differs from infer's SVG ({flags:?})");
            assert!(
                written.contains("viewBox=\"0 0 60 40\"") && written.contains("<g class=\"region-"),
                "{written}"
            );
        }
        // A picture of ramps: with linear fills every drawing writes gradients.
        if fills == Some(infer::Fills::Linear) {
            let written = std::fs::read_to_string(svgs.join("a-b-24.svg")).unwrap();
            assert!(written.contains("<linearGradient"), "{flags:?}: no gradient");
        }
    }
    std::fs::remove_dir_all(&dir).unwrap();
    std::fs::remove_dir_all(&written_to).unwrap();
}

/// `--sweep` adds a rate–distortion section, SuperSVG-B and the fallback alone at each budget
/// (files grow with the budget), and its chart beside the report: an SVG, and the PNG of it.
#[test]
fn a_sweep_reports_each_budget_and_draws_the_chart() {
    let dir = std::env::temp_dir().join(format!("supersvg-eval-sweep-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let picture =
        image::RgbImage::from_fn(48, 32, |x, y| image::Rgb([(x * 5) as u8, (y * 7) as u8, (x * y) as u8]));
    picture.save(dir.join("a.png")).unwrap();
    let out = dir.join("report.md");
    let result = Command::new(EVAL)
        .arg(&dir)
        .args(["--out", out.to_str().unwrap(), "--paths", "16", "--sweep", "4,16,64", "--size", "48"])
        .args(["--peers", "fallback"])
        .output()
        .unwrap();
    assert!(result.status.success(), "{}", String::from_utf8_lossy(&result.stderr));
    let report = std::fs::read_to_string(&out).unwrap();
    let section = report.split("## Rate and distortion").nth(1).unwrap_or_else(|| panic!("{report}"));
    for method in ["SuperSVG-B (ours)", "fallback alone (traced regions in their fills)"] {
        let kilobytes: Vec<f64> = ["4 paths", "16 paths", "64 paths"]
            .iter()
            .map(|setting| {
                let row = format!("| {method} | {setting} |");
                let line = section
                    .lines()
                    .find(|l| l.starts_with(&row))
                    .unwrap_or_else(|| panic!("no {row} in {section}"));
                line.split('|').map(str::trim).nth(3).unwrap().parse().unwrap()
            })
            .collect();
        assert!(kilobytes[0] < kilobytes[1] && kilobytes[1] < kilobytes[2], "{method}: {kilobytes:?}");
    }
    let chart = std::fs::read_to_string(dir.join("report-rate.svg")).unwrap();
    // A PSNR panel, and an LPIPS one where its weights are installed: one line per method in each.
    let panels = chart.matches("against file size</text>").count();
    assert!(panels >= 1 && chart.matches("<polyline").count() == 2 * panels, "{chart}");
    let png = image::open(dir.join("report-rate.png")).unwrap();
    let width: f64 = chart.split("width=\"").nth(1).unwrap().split('"').next().unwrap().parse().unwrap();
    assert_eq!(png.width(), width.ceil() as u32);
    std::fs::remove_dir_all(&dir).unwrap();
}

const TUNE: &str = env!("CARGO_BIN_EXE_tune");

/// No report lands on a model file `eval` or `tune` reads (or `tune` rewrites), whatever its
/// name, and a file named after the report that `eval` did not write (`keep.png` beside
/// `--out keep.md`) is never replaced; one it wrote is, on the next run. A file where `--svgs`
/// wants a folder is said as such.
#[test]
fn reports_never_replace_inputs_or_files_they_did_not_write() {
    let dir = std::env::temp_dir().join(format!("supersvg-eval-inputs-{}", std::process::id()));
    let images = dir.join("images");
    std::fs::create_dir_all(&images).unwrap();
    image::RgbImage::from_fn(24, 16, |x, y| image::Rgb([(x * 9) as u8, (y * 13) as u8, 90]))
        .save(images.join("a.png"))
        .unwrap();
    let models = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../models");
    for name in ["coarse.ckpt", "mover.ckpt", "refine.ckpt"] {
        std::fs::copy(models.join(name), dir.join(name)).unwrap();
    }
    let p = |name: &str| dir.join(name).to_str().unwrap().to_string();
    let original = |name: &str| std::fs::read(models.join(name)).unwrap();
    let refused = |program: &str, args: &[String], says: &str| {
        let result = Command::new(program).args(args).output().unwrap();
        let stderr = String::from_utf8_lossy(&result.stderr).into_owned();
        assert_eq!(result.status.code(), Some(1), "{args:?}: {stderr}");
        assert!(stderr.contains(says), "{args:?}: {stderr}");
    };
    let eval = |flags: &[&str]| -> Vec<String> {
        [&[p("images").as_str(), "--peers", "", "--paths", "20", "--size", "24"][..], flags]
            .concat()
            .into_iter()
            .map(String::from)
            .collect()
    };
    for (flag, name) in [("--coarse", "coarse.ckpt"), ("--mover", "mover.ckpt"), ("--refine", "refine.ckpt")]
    {
        refused(EVAL, &eval(&[flag, &p(name), "--out", &p(name)]), "refusing to overwrite");
        assert_eq!(std::fs::read(dir.join(name)).unwrap(), original(name), "{name} changed");
    }
    let tune = |flags: &[&str]| -> Vec<String> {
        [
            &[
                p("images").as_str(),
                "--paths",
                "20",
                "--size",
                "24",
                "--coarse-share",
                "0",
                "--refine-share",
                "0",
            ][..],
            flags,
        ]
        .concat()
        .into_iter()
        .map(String::from)
        .collect()
    };
    for (flag, name) in [("--coarse", "coarse.ckpt"), ("--refine", "refine.ckpt"), ("--write", "coarse.ckpt")]
    {
        refused(TUNE, &tune(&[flag, &p(name), "--out", &p(name)]), "refusing to overwrite");
        assert_eq!(std::fs::read(dir.join(name)).unwrap(), original(name), "{name} changed");
    }

    std::fs::write(dir.join("keep.png"), b"a picture of the user's own").unwrap();
    refused(EVAL, &eval(&["--out", &p("keep.md")]), "keep.png: exists and was not written by eval");
    assert_eq!(std::fs::read(dir.join("keep.png")).unwrap(), b"a picture of the user's own");
    std::fs::remove_file(dir.join("keep.png")).unwrap();
    for run in 0..2 {
        let result = Command::new(EVAL).args(eval(&["--out", &p("keep.md")])).output().unwrap();
        assert!(result.status.success(), "run {run}: {}", String::from_utf8_lossy(&result.stderr));
    }
    // 24 × 16 is too small for LPIPS's network: the report says why its column is empty.
    let report = std::fs::read_to_string(dir.join("keep.md")).unwrap();
    assert!(
        report.contains("LPIPS skipped:") || report.contains("LPIPS is not defined under 31 pixels a side"),
        "{report}"
    );
    std::fs::write(dir.join("plain"), b"a file").unwrap();
    refused(EVAL, &eval(&["--out", &p("r.md"), "--svgs", &p("plain")]), "plain: is a file, not a folder");
    // A damaged model file is refused before any image is drawn, by both programs.
    let mut damaged = original("coarse.ckpt");
    let last = damaged.len() - 3;
    damaged[last] ^= 1;
    std::fs::write(dir.join("coarse.ckpt"), damaged).unwrap();
    refused(EVAL, &eval(&["--coarse", &p("coarse.ckpt"), "--out", &p("r.md")]), "damaged checkpoint");
    refused(TUNE, &tune(&["--coarse", &p("coarse.ckpt"), "--out", &p("t.md")]), "damaged checkpoint");
    assert!(!dir.join("r.md").exists() && !dir.join("t.md").exists());
    std::fs::remove_dir_all(&dir).unwrap();
}
