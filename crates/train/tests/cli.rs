//! The training programs refuse bad input with a clear message and a failing exit code.

use std::path::{Path, PathBuf};
use std::process::Command;

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("supersvg-cli-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn smoke(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../configs").join(name)
}

/// Runs a program, expecting failure; returns its stderr.
fn fails(program: &str, args: &[&str]) -> String {
    let output = Command::new(program).args(args).output().unwrap();
    assert!(!output.status.success(), "{program} {args:?} should fail");
    assert_eq!(output.status.code(), Some(1));
    String::from_utf8(output.stderr).unwrap()
}

const COARSE: &str = env!("CARGO_BIN_EXE_train-coarse");
const REFINE: &str = env!("CARGO_BIN_EXE_train-refine");
const EXPORT: &str = env!("CARGO_BIN_EXE_export-model");

#[test]
fn bad_configs_are_refused_by_name() {
    let dir = scratch("config");
    let config = dir.join("bad.toml");
    std::fs::write(&config, "[data]\nsynthetic = true\n[train]\nbatch_sise = 4\n").unwrap();
    let err = fails(COARSE, &["--config", config.to_str().unwrap(), "--out", dir.to_str().unwrap()]);
    assert!(err.contains("bad.toml") && err.contains("batch_sise"), "{err}");

    std::fs::write(&config, "[data]\nsynthetic = true\n[train]\nlr = -1.0\n").unwrap();
    let err = fails(COARSE, &["--config", config.to_str().unwrap()]);
    assert!(err.contains("train.lr must be positive"), "{err}");

    let err = fails(COARSE, &["--config", dir.join("missing.toml").to_str().unwrap()]);
    assert!(err.contains("missing.toml"), "{err}");

    // Steps are at least one, from the config or the flag: no untrained checkpoint, no NaN loss.
    let smoke_coarse = smoke("smoke-coarse.toml");
    let out = dir.join("zero");
    let refused = Command::new(COARSE)
        .args(["--config", smoke_coarse.to_str().unwrap(), "--out", out.to_str().unwrap(), "--steps", "0"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&refused.stderr);
    assert_eq!(refused.status.code(), Some(2), "a usage error: {err}");
    assert!(err.contains("--steps") && err.contains("'0'"), "{err}");
    assert!(!out.exists(), "a refused run wrote {}", out.display());
}

#[test]
fn an_empty_data_folder_is_refused() {
    let dir = scratch("data");
    let images = dir.join("images");
    std::fs::create_dir_all(&images).unwrap();
    let config = dir.join("empty.toml");
    let text = std::fs::read_to_string(smoke("smoke-coarse.toml")).unwrap().replace(
        "[data]\nsynthetic = true",
        &format!("[data]\nsynthetic = false\nimages = {:?}", images.to_str().unwrap()),
    );
    std::fs::write(&config, text).unwrap();
    let err =
        fails(COARSE, &["--config", config.to_str().unwrap(), "--out", dir.join("run").to_str().unwrap()]);
    assert!(err.contains("no readable image") && err.contains("images"), "{err}");
}

#[test]
fn refinement_needs_a_coarse_checkpoint() {
    let dir = scratch("init");
    let config = smoke("smoke-refine.toml");
    let missing = dir.join("nowhere.ckpt");
    let err = fails(REFINE, &["--config", config.to_str().unwrap(), "--init", missing.to_str().unwrap()]);
    assert!(err.contains("nowhere.ckpt") && err.contains("no such file"), "{err}");

    // A refinement checkpoint where a coarse one is needed: train one for a single step.
    let coarse_dir = dir.join("coarse");
    let ok = Command::new(COARSE)
        .args([
            "--config",
            smoke("smoke-coarse.toml").to_str().unwrap(),
            "--out",
            coarse_dir.to_str().unwrap(),
            "--steps",
            "1",
        ])
        .output()
        .unwrap();
    assert!(ok.status.success(), "{}", String::from_utf8_lossy(&ok.stderr));
    let refine_dir = dir.join("refine");
    let coarse_ckpt = coarse_dir.join("coarse.ckpt");
    let ok = Command::new(REFINE)
        .args([
            "--config",
            config.to_str().unwrap(),
            "--init",
            coarse_ckpt.to_str().unwrap(),
            "--out",
            refine_dir.to_str().unwrap(),
            "--steps",
            "1",
        ])
        .output()
        .unwrap();
    assert!(ok.status.success(), "{}", String::from_utf8_lossy(&ok.stderr));
    let wrong = refine_dir.join("refine.ckpt");
    let err = fails(REFINE, &["--config", config.to_str().unwrap(), "--init", wrong.to_str().unwrap()]);
    assert!(err.contains("refine checkpoint") && err.contains("coarse checkpoint is needed"), "{err}");

    // Resuming where nothing was trained.
    let err = fails(
        COARSE,
        &[
            "--config",
            smoke("smoke-coarse.toml").to_str().unwrap(),
            "--out",
            dir.join("fresh").to_str().unwrap(),
            "--resume",
        ],
    );
    assert!(err.contains("coarse.ckpt"), "{err}");

    // Resuming from an exported (inference) checkpoint: its optimizer state is gone.
    let exported_dir = dir.join("exported");
    std::fs::create_dir_all(&exported_dir).unwrap();
    let exported = exported_dir.join("coarse.ckpt");
    let ok = Command::new(EXPORT)
        .args([coarse_ckpt.to_str().unwrap(), exported.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(ok.status.success(), "{}", String::from_utf8_lossy(&ok.stderr));
    // An export over its own input, by any name, is refused before it reads: the run can still resume.
    let before = std::fs::read(&coarse_ckpt).unwrap();
    let dotted = coarse_ckpt.parent().unwrap().join("../").join(coarse_ckpt.strip_prefix(&dir).unwrap());
    for output in [&coarse_ckpt, &dotted] {
        let err = fails(EXPORT, &[coarse_ckpt.to_str().unwrap(), output.to_str().unwrap()]);
        assert!(err.contains("refusing to overwrite"), "{err}");
    }
    assert!(std::fs::read(&coarse_ckpt).unwrap() == before, "the training checkpoint changed");
    let err = fails(
        COARSE,
        &[
            "--config",
            smoke("smoke-coarse.toml").to_str().unwrap(),
            "--out",
            exported_dir.to_str().unwrap(),
            "--resume",
        ],
    );
    assert!(err.contains("cannot resume") && err.contains("no optimizer state"), "{err}");

    // Fine-tuning E_c starts from a coarse checkpoint of the config's model (an exported one
    // will do: no optimizer state is needed); a refinement checkpoint or another model is refused.
    let smoke_coarse = smoke("smoke-coarse.toml");
    let tuned = dir.join("tuned");
    let args = |init: &Path, out: &Path| {
        ["--config", smoke_coarse.to_str().unwrap(), "--out", out.to_str().unwrap(), "--steps", "1"]
            .into_iter()
            .map(String::from)
            .chain(["--init".to_string(), init.to_str().unwrap().to_string()])
            .collect::<Vec<_>>()
    };
    let ok = Command::new(COARSE).args(args(&exported, &tuned)).output().unwrap();
    assert!(ok.status.success(), "{}", String::from_utf8_lossy(&ok.stderr));
    assert!(tuned.join("coarse.ckpt").is_file());
    let refused = |init: &Path| {
        let args = args(init, &dir.join("refused"));
        fails(COARSE, &args.iter().map(String::as_str).collect::<Vec<_>>())
    };
    let err = refused(&wrong);
    assert!(err.contains("refine.ckpt") && err.contains("refine checkpoint"), "{err}");
    let bundled = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../models/coarse.ckpt");
    let err = refused(&bundled);
    assert!(err.contains("models/coarse.ckpt") && err.contains("is not the [model] of"), "{err}");
    std::fs::remove_dir_all(&dir).unwrap();
}

const MOVER: &str = env!("CARGO_BIN_EXE_train-mover");

/// `train-mover` on one small image: it refuses unknown keys and a folder it would overwrite by
/// name, and a run of two epochs resumed after its first gives the weights of one run of two
/// (the teacher's samples read back, the optimizer restored), which `export-model` ships.
#[test]
fn the_mover_trains_resumes_exactly_and_exports() {
    let dir = scratch("mover");
    let image = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets/astronaut.jpg");
    let config = |epochs: usize, extra: &str| {
        let path = dir.join(format!("mover-{epochs}.toml"));
        let text = format!(
            "[data]\nimages = [{image:?}]\npaths = [24]\nsize = 48\n[teacher]\nsteps = 5\npad = 5\n\
             [train]\nepochs = {epochs}\nbatch = 64\nlearning_rate = 1e-3\nseed = 1\nheld_out = 0.2\n{extra}"
        );
        std::fs::write(&path, text).unwrap();
        path.to_str().unwrap().to_string()
    };
    let err = fails(MOVER, &["--config", &config(1, "speed = 2\n"), "--out", dir.to_str().unwrap()]);
    assert!(err.contains("mover-1.toml") && err.contains("speed"), "{err}");
    let seen = format!("[validation]\nimages = [{image:?}]\n");
    let err = fails(MOVER, &["--config", &config(1, &seen), "--out", dir.to_str().unwrap()]);
    assert!(err.contains("validation.images: ") && err.contains("is the image"), "{err}");
    // Another picture: the astronaut turned round.
    let held = dir.join("held-out.png");
    image::open(&image).unwrap().fliph().save(&held).unwrap();
    let validation = format!("[validation]\nimages = [{held:?}]\n");
    let train = |config: &str, out: &Path, extra: &[&str]| {
        let output = Command::new(MOVER)
            .args(["--config", config, "--out", out.to_str().unwrap()])
            .args(extra)
            .output();
        let output = output.unwrap();
        let stderr = String::from_utf8_lossy(&output.stderr).into_owned();
        assert!(output.status.success(), "{stderr}");
        stderr
    };
    let (once, twice) = (dir.join("once"), dir.join("twice"));
    let log = train(&config(2, &validation), &once, &[]);
    assert_eq!(log.matches("at inference, 24 paths").count(), 2, "{log}");
    train(&config(1, ""), &twice, &[]);
    let err = fails(MOVER, &["--config", &config(2, ""), "--out", twice.to_str().unwrap()]);
    assert!(err.contains("mover.ckpt exists") && err.contains("--resume"), "{err}");
    train(&config(2, ""), &twice, &["--resume"]);
    let file = |run: &Path| model::MoverCheckpoint::load(&run.join("mover.ckpt")).unwrap();
    let weights = |run: &Path| {
        let file = file(run);
        assert!(file.optimizer.is_some());
        file.weights_checksum()
    };
    // Scoring each epoch at inference leaves the weights as they were.
    assert_eq!(weights(&once), weights(&twice));
    let state =
        |run: &Path| -> train::MoverState { serde_json::from_str(&file(run).training.unwrap()).unwrap() };
    let scores = state(&once).at_inference;
    assert_eq!(
        scores.iter().map(|epoch| (epoch.len(), epoch[0].images)).collect::<Vec<_>>(),
        [(1, 1), (1, 1)]
    );
    assert!(state(&twice).at_inference.is_empty());
    let shipped = dir.join("shipped.ckpt");
    let output = Command::new(EXPORT)
        .args([once.join("mover.ckpt").to_str().unwrap(), shipped.to_str().unwrap(), "--dtype", "f32"])
        .output()
        .unwrap();
    assert!(output.status.success() && String::from_utf8_lossy(&output.stdout).contains("move model"));
    let file = model::MoverCheckpoint::load(&shipped).unwrap();
    assert_eq!((file.optimizer.is_none(), file.weights_checksum()), (true, weights(&once)));

    // A damaged mover's file is said to be damaged, not of an unknown format.
    let mut bytes = std::fs::read(&shipped).unwrap();
    let last = bytes.len() - 3;
    bytes[last] ^= 1;
    let damaged = dir.join("damaged.ckpt");
    std::fs::write(&damaged, bytes).unwrap();
    let err = fails(EXPORT, &[damaged.to_str().unwrap(), dir.join("out.ckpt").to_str().unwrap()]);
    assert!(err.contains("damaged.ckpt: a damaged checkpoint") && !err.contains("unsupported"), "{err}");
    // A file where the run's folder goes, and a held-out image that is not there, are said
    // before any work, the image's path once.
    let plain = dir.join("plain");
    std::fs::write(&plain, b"a file").unwrap();
    let err = fails(MOVER, &["--config", &config(1, ""), "--out", plain.to_str().unwrap()]);
    assert!(err.contains("plain: is a file, not a folder"), "{err}");
    let missing = dir.join("missing.png");
    let absent = format!("[validation]\nimages = [{missing:?}]\n");
    let err = fails(MOVER, &["--config", &config(1, &absent), "--out", dir.join("absent").to_str().unwrap()]);
    assert!(err.contains("validation.images") && err.matches("missing.png").count() == 1, "{err}");
    assert!(!err.contains("points in"), "the teacher worked first: {err}");
}

const OPTIMIZER: &str = env!("CARGO_BIN_EXE_train-optimizer");

/// `train-optimizer` on one small image: four updates in one run give the weights of two, then
/// two more resumed (the optimizer and the scores restored), and `export-model` ships them.
#[test]
fn the_learned_optimizer_trains_resumes_exactly_and_exports() {
    let dir = scratch("optimizer");
    let image = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets/astronaut.jpg");
    let held = dir.join("held-out.png");
    image::open(&image).unwrap().fliph().save(&held).unwrap();
    let config = |updates: usize| {
        let path = dir.join(format!("optimizer-{updates}.toml"));
        let drawings = |image: &Path| format!("images = [{image:?}]\npaths = [\"24\"]\nsize = 48\n");
        let text = format!(
            "[data]\n{}[rollout]\nsteps = 2\ngrow = 1\n[train]\nupdates = {updates}\nlearning_rate = 1e-3\n\
             seed = 1\nfrom_mover = true\nevery = 2\n[validation]\n{}[scoring]\nseconds = 0.05\n",
            drawings(&image),
            drawings(&held)
        );
        std::fs::write(&path, text).unwrap();
        path.to_str().unwrap().to_string()
    };
    let train = |config: &str, out: &Path, extra: &[&str]| {
        let output = Command::new(OPTIMIZER)
            .args(["--config", config, "--out", out.to_str().unwrap()])
            .args(extra)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&output.stderr).into_owned();
        assert!(output.status.success(), "{stderr}");
        stderr
    };
    let (once, twice) = (dir.join("once"), dir.join("twice"));
    let log = train(&config(4), &once, &[]);
    assert_eq!(log.matches("F for 0.05 s with E_o").count(), 2, "{log}");
    train(&config(2), &twice, &[]);
    let err = fails(OPTIMIZER, &["--config", &config(4), "--out", twice.to_str().unwrap()]);
    assert!(err.contains("optimizer.ckpt exists") && err.contains("--resume"), "{err}");
    train(&config(4), &twice, &["--resume"]);
    let file = |run: &Path| model::OptimizerCheckpoint::load(&run.join("optimizer.ckpt")).unwrap();
    let state = |run: &Path| -> train::OptimizerState {
        serde_json::from_str(&file(run).training.expect("the trainer's state")).unwrap()
    };
    let (a, b) = (file(&once), file(&twice));
    assert!(a.optimizer.is_some() && b.optimizer.is_some());
    assert_eq!(a.weights_checksum(), b.weights_checksum());
    let (a, b) = (state(&once), state(&twice));
    assert_eq!((a.update, b.update), (4, 4));
    assert_eq!(a.scores.iter().map(|s| s.update).collect::<Vec<_>>(), [2, 4]);
    assert_eq!(b.scores.iter().map(|s| s.update).collect::<Vec<_>>(), [2, 4]);
    let finite = |s: &train::OptimizerScore| s.with.is_finite() && s.without.is_finite();
    assert!(a.scores.iter().chain(&b.scores).all(finite), "{a:?} {b:?}");

    let shipped = dir.join("shipped.ckpt");
    let output = Command::new(EXPORT)
        .args([once.join("optimizer.ckpt").to_str().unwrap(), shipped.to_str().unwrap(), "--dtype", "f32"])
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(output.status.success() && stdout.contains("optimize model"), "{stdout}");
    let exported = model::OptimizerCheckpoint::load(&shipped).unwrap();
    assert!(exported.optimizer.is_none());
    assert_eq!(exported.weights_checksum(), file(&once).weights_checksum());
    std::fs::remove_dir_all(&dir).unwrap();
}
