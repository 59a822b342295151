//! The trainers under faults: a trained checkpoint is never replaced by accident, a stop by
//! SIGTERM saves one, data that can give no sample fails fast, and resuming refuses a model it
//! was not trained as.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use common::testing::{stderr_lines, wait_within};

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

/// `program --config CONFIG --out OUT EXTRA…`, stderr piped.
fn trainer(program: &str, config: &Path, out: &Path, extra: &[&str]) -> Child {
    Command::new(program)
        .args(["--config", config.to_str().unwrap(), "--out", out.to_str().unwrap()])
        .args(extra)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap()
}

fn coarse(config: &Path, out: &Path, extra: &[&str]) -> Child {
    trainer(COARSE, config, out, extra)
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

const MOVER: &str = env!("CARGO_BIN_EXE_train-mover");

/// A mover config for `images` at 48 px, with `teacher` steps and `extra` lines.
fn mover_config(dir: &Path, name: &str, images: &[&Path], steps: u64, extra: &str) -> PathBuf {
    let path = dir.join(name);
    let images: Vec<String> = images.iter().map(|image| format!("{image:?}")).collect();
    let text = format!(
        "[data]\nimages = [{}]\npaths = [24]\nsize = 48\n[teacher]\nsteps = {steps}\npad = 5\n\
         [train]\nepochs = 1\nbatch = 64\nlearning_rate = 1e-3\nseed = 1\nheld_out = 0.2\n{extra}",
        images.join(", ")
    );
    std::fs::write(&path, text).unwrap();
    path
}

fn mover(config: &Path, out: &Path, extra: &[&str]) -> Child {
    trainer(MOVER, config, out, extra)
}

fn astronaut() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets/astronaut.jpg")
}

/// Waits (at most two minutes) for a line of `lines` that holds `text`.
fn wait_for(lines: &std::sync::mpsc::Receiver<String>, text: &str) {
    common::testing::wait_for(lines, text, 120);
}

/// Settings that would run for ever or train on nothing are refused by name before any work:
/// a teacher of 10^11 steps, an infinite or absurd learning rate.
#[test]
fn the_mover_refuses_settings_it_cannot_finish() {
    let dir = scratch("mover-settings");
    let image = astronaut();
    for (steps, rate, says) in [
        (100_000_000_000u64, "1e-3", "teacher.steps: 1 to 10000"),
        (5, "inf", "train.learning_rate"),
        (5, "1e30", "train.learning_rate"),
    ] {
        let config = mover_config(&dir, "bad.toml", &[&image], steps, "");
        let written = std::fs::read_to_string(&config).unwrap();
        std::fs::write(&config, written.replace("learning_rate = 1e-3", &format!("learning_rate = {rate}")))
            .unwrap();
        let out = dir.join("run");
        let result = wait_within(mover(&config, &out, &[]), 60);
        let stderr = text(&result.stderr);
        assert_eq!(result.status.code(), Some(1), "{stderr}");
        assert!(stderr.contains("bad.toml") && stderr.contains(says), "{stderr}");
        assert!(!out.join("mover.ckpt").exists());
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A stop in the teacher's work (the longest it may be) is acted on at once: the run ends with
/// 130, saying that running the same command again goes on, and leaves no partial samples. While
/// it runs, a second run on the same folder is refused, and the first's files stay its own.
#[test]
fn the_mover_hears_a_stop_in_its_teacher_and_holds_its_folder() {
    let dir = scratch("mover-stop");
    let config = mover_config(&dir, "long.toml", &[&astronaut()], 10_000, "");
    let out = dir.join("run");
    let mut first = mover(&config, &out, &[]);
    let lines = stderr_lines(&mut first);
    wait_for(&lines, "teacher:");
    let second = wait_within(mover(&config, &out, &["--overwrite"]), 60);
    let stderr = text(&second.stderr);
    assert_eq!(second.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("another run is writing to this folder"), "{stderr}");
    let status = Command::new("kill").args(["-TERM", &first.id().to_string()]).status().unwrap();
    assert!(status.success());
    let stopped = wait_within(first, 60);
    let said: Vec<String> = lines.into_iter().collect();
    assert_eq!(stopped.status.code(), Some(130), "{said:#?}");
    let said = said.join("\n");
    assert!(
        said.contains("interrupted before training began") && said.contains("run the same command again"),
        "{said}"
    );
    assert_eq!(std::fs::read_dir(out.join("samples")).unwrap().count(), 0, "a partial samples file");
    assert!(!out.join("mover.ckpt").exists());
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The teacher's samples are kept under what made them: a changed teacher makes them again;
/// samples with a NaN are refused by name; pictures with nothing to move fail before training,
/// with no checkpoint claimed; a `[validation]` image is told from a training image by its
/// contents, not its name; and a closed stderr never stops the run.
#[test]
fn the_movers_samples_are_what_their_settings_make() {
    let dir = scratch("mover-samples");
    let image = astronaut();
    let out = dir.join("run");
    let run = |config: &Path, extra: &[&str]| wait_within(mover(config, &out, extra), 300);
    let first = run(&mover_config(&dir, "five.toml", &[&image], 5, ""), &[]);
    assert!(first.status.success(), "{}", text(&first.stderr));
    assert!(text(&first.stderr).contains("points in"), "{}", text(&first.stderr));
    let again = run(&mover_config(&dir, "five.toml", &[&image], 5, ""), &["--overwrite"]);
    assert!(!text(&again.stderr).contains("points in"), "made again: {}", text(&again.stderr));
    let six = run(&mover_config(&dir, "six.toml", &[&image], 6, ""), &["--overwrite"]);
    assert!(text(&six.stderr).contains("points in"), "read back: {}", text(&six.stderr));

    // A stored samples file damaged into NaNs.
    let stored: Vec<PathBuf> =
        std::fs::read_dir(out.join("samples")).unwrap().flatten().map(|e| e.path()).collect();
    assert_eq!(stored.len(), 2, "{stored:?}");
    for file in &stored {
        let mut bytes = std::fs::read(file).unwrap();
        bytes[..4].copy_from_slice(&f32::NAN.to_le_bytes());
        std::fs::write(file, bytes).unwrap();
    }
    let damaged = run(&mover_config(&dir, "six.toml", &[&image], 6, ""), &["--overwrite"]);
    let stderr = text(&damaged.stderr);
    assert_eq!(damaged.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains(".f32") && stderr.contains("NaN"), "{stderr}");

    let flat = dir.join("flat.png");
    image::RgbImage::from_pixel(64, 64, image::Rgb([90, 90, 90])).save(&flat).unwrap();
    let nothing =
        wait_within(mover(&mover_config(&dir, "flat.toml", &[&flat], 5, ""), &dir.join("flat"), &[]), 120);
    let stderr = text(&nothing.stderr);
    assert_eq!(nothing.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("no point to move") && !stderr.contains("checkpoint"), "{stderr}");
    assert!(!dir.join("flat/mover.ckpt").exists());

    // The same picture under another name is no held-out image; another picture under a
    // training image's name is.
    let twin = dir.join("twin.jpg");
    std::fs::copy(&image, &twin).unwrap();
    let validation = |held: &Path| format!("[validation]\nimages = [{held:?}]\n");
    let refused = run(&mover_config(&dir, "twin.toml", &[&image], 5, &validation(&twin)), &["--overwrite"]);
    let stderr = text(&refused.stderr);
    assert_eq!(refused.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("twin.jpg is the image") && stderr.contains("astronaut.jpg"), "{stderr}");
    std::fs::create_dir_all(dir.join("other")).unwrap();
    let namesake = dir.join("other/astronaut.jpg");
    image::open(&image).unwrap().fliph().save(&namesake).unwrap();
    let named = dir.join("named");
    let config = mover_config(&dir, "namesake.toml", &[&image], 5, &validation(&namesake));
    let mut child = mover(&config, &named, &[]);
    // Its stderr read for one line and closed: the run goes on to its checkpoint.
    let lines = stderr_lines(&mut child);
    wait_for(&lines, "teacher:");
    drop(lines);
    let done = wait_within(child, 300);
    assert!(done.status.success(), "{:?}", done.status);
    assert!(named.join("mover.ckpt").is_file());
    std::fs::remove_dir_all(&dir).unwrap();
}
