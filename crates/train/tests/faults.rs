//! The trainers under faults: a trained checkpoint is never replaced by accident, a stop by
//! SIGTERM saves one, data that can give no sample fails fast, and resuming refuses a model it
//! was not trained as.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use common::testing::wait_within;

const COARSE: &str = env!("CARGO_BIN_EXE_train-coarse");
const REFINE: &str = env!("CARGO_BIN_EXE_train-refine");

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("supersvg-faults-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn smoke(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../configs").join(name)
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

fn coarse(config: &Path, out: &Path, extra: &[&str]) -> Child {
    Command::new(COARSE)
        .args(["--config", config.to_str().unwrap(), "--out", out.to_str().unwrap()])
        .args(extra)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap()
}

/// How many training lines of `metrics.jsonl` are for `step`.
fn lines_at(dir: &Path, step: usize) -> usize {
    let metrics = std::fs::read_to_string(dir.join("metrics.jsonl")).unwrap();
    let lines = metrics.lines().map(|line| serde_json::from_str::<serde_json::Value>(line).unwrap());
    lines.filter(|line| line["step"] == step && line.get("loss").is_some()).count()
}

#[test]
fn a_trained_checkpoint_is_replaced_only_when_asked() {
    let dir = scratch("exists");
    let out = dir.join("run");
    let config = smoke("smoke-coarse.toml");
    let first = wait_within(coarse(&config, &out, &["--steps", "5"]), 300);
    assert!(first.status.success(), "{}", text(&first.stderr));
    let trained = std::fs::read(out.join("coarse.ckpt")).unwrap();
    let again = wait_within(coarse(&config, &out, &["--steps", "5"]), 300);
    assert_eq!(again.status.code(), Some(1));
    assert!(
        text(&again.stderr).contains("already there") && text(&again.stderr).contains("--resume"),
        "{}",
        text(&again.stderr)
    );
    assert_eq!(std::fs::read(out.join("coarse.ckpt")).unwrap(), trained, "the checkpoint is untouched");
    let fresh = wait_within(coarse(&config, &out, &["--steps", "5", "--overwrite"]), 300);
    assert!(fresh.status.success(), "{}", text(&fresh.stderr));
    assert_eq!(lines_at(&out, 5), 1, "the metrics file holds one run's series");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn sigterm_saves_a_checkpoint_to_resume_from() {
    let dir = scratch("sigterm");
    let out = dir.join("run");
    let config = smoke("smoke-coarse.toml");
    let child = coarse(&config, &out, &["--steps", "100000"]);
    // Wait for the first logged steps, then stop it as `timeout` or Slurm would.
    let started = Instant::now();
    while !std::fs::read_to_string(out.join("metrics.jsonl")).is_ok_and(|m| m.lines().count() >= 2) {
        assert!(started.elapsed() < Duration::from_secs(240), "no step logged");
        std::thread::sleep(Duration::from_millis(50));
    }
    let status = Command::new("kill").args(["-TERM", &child.id().to_string()]).status().unwrap();
    assert!(status.success());
    let stopped = wait_within(child, 120);
    assert_eq!(stopped.status.code(), Some(130), "{}", text(&stopped.stderr));
    assert!(text(&stopped.stderr).contains("continue with --resume"), "{}", text(&stopped.stderr));
    let resumed = wait_within(coarse(&config, &out, &["--steps", "20", "--resume"]), 300);
    assert!(resumed.status.success(), "{}", text(&resumed.stderr));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn images_too_small_for_a_sample_fail_fast_naming_the_folder() {
    let dir = scratch("tiny");
    let images = dir.join("images");
    std::fs::create_dir_all(&images).unwrap();
    for i in 0..3 {
        image::RgbImage::from_pixel(3, 3, image::Rgb([i * 80, 20, 40]))
            .save(images.join(format!("{i}.png")))
            .unwrap();
    }
    let config = dir.join("tiny.toml");
    let text_config = std::fs::read_to_string(smoke("smoke-coarse.toml")).unwrap().replace(
        "[data]\nsynthetic = true",
        &format!("[data]\nsynthetic = false\nimages = {:?}", images.to_str().unwrap()),
    );
    std::fs::write(&config, text_config).unwrap();
    let failed = wait_within(coarse(&config, &dir.join("run"), &[]), 120);
    assert_eq!(failed.status.code(), Some(1));
    let stderr = text(&failed.stderr);
    assert!(stderr.contains("no region of 16 pixels") && stderr.contains("images"), "{stderr}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn resuming_refuses_another_models_configuration() {
    let dir = scratch("init");
    let (small, other) = (dir.join("small"), dir.join("other"));
    let config = smoke("smoke-coarse.toml");
    let wider = dir.join("wider.toml");
    std::fs::write(
        &wider,
        std::fs::read_to_string(&config).unwrap().replace("embed_dim = 48", "embed_dim = 64"),
    )
    .unwrap();
    for (config, out) in [(&config, &small), (&wider, &other)] {
        let done = wait_within(coarse(config, out, &["--steps", "2"]), 300);
        assert!(done.status.success(), "{}", text(&done.stderr));
    }
    let refine_out = dir.join("refine");
    let refine = |init: &Path, extra: &[&str]| {
        let child = Command::new(REFINE)
            .args([
                "--config",
                smoke("smoke-refine.toml").to_str().unwrap(),
                "--out",
                refine_out.to_str().unwrap(),
            ])
            .args(["--init", init.join("coarse.ckpt").to_str().unwrap()])
            .args(extra)
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        wait_within(child, 300)
    };
    let first = refine(&small, &["--steps", "2"]);
    assert!(first.status.success(), "{}", text(&first.stderr));
    let mixed = refine(&other, &["--resume", "--steps", "4"]);
    assert_eq!(mixed.status.code(), Some(1));
    let stderr = text(&mixed.stderr);
    assert!(stderr.contains("cannot resume") && stderr.contains("embed_dim"), "{stderr}");
    std::fs::remove_dir_all(&dir).unwrap();
}
