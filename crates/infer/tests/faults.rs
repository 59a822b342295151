//! `infer` under faults: planted links, stops, huge inputs, broken pipes and misleading inputs
//! never lose a file, follow a link, hang or say the wrong thing.

use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::sync::mpsc::Receiver;
use std::time::Duration;

use common::testing::{stderr_lines, wait_within};

mod support;

use support::{Fixture, INFER, text};

fn spawn(fixture: &Fixture, args: &[&str]) -> Child {
    Command::new(INFER)
        .args(args)
        .args(["--coarse", fixture.path("coarse.ckpt").to_str().unwrap()])
        .args(["--refine", fixture.path("refine.ckpt").to_str().unwrap()])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap()
}

fn signal(child: &Child, name: &str) {
    let status = Command::new("kill").args([&format!("-{name}"), &child.id().to_string()]).status().unwrap();
    assert!(status.success(), "kill -{name}");
}

/// Links planted where temporaries would go under predictable names, pointing at files outside:
/// none of those files changes, and the outputs are regular files.
#[cfg(unix)]
#[test]
fn planted_links_are_never_followed() {
    let fixture = Fixture::new("links");
    let shared = fixture.path("shared");
    std::fs::create_dir_all(&shared).unwrap();
    let victims: Vec<_> = (0..3).map(|i| fixture.path(&format!("victim-{i}"))).collect();
    for victim in &victims {
        std::fs::write(victim, b"precious").unwrap();
    }
    // The names the old temporaries took (pid-based), for a range of pids, and a few others.
    for pid in 1..400u32 {
        let victim = &victims[pid as usize % 3];
        for name in
            [format!(".supersvg-probe-{pid}"), format!(".out.svg.{pid}.tmp"), format!(".out.png.{pid}.tmp")]
        {
            std::os::unix::fs::symlink(victim, shared.join(name)).unwrap();
        }
    }
    let (svg, preview) = (shared.join("out.svg"), shared.join("out.png"));
    let photo = fixture.path("photo.png");
    let args = [photo.to_str().unwrap(), "-o", svg.to_str().unwrap(), "--preview", preview.to_str().unwrap()];
    let result = wait_within(spawn(&fixture, &[&args[..], &["--paths", "20"]].concat()), 120);
    assert!(result.status.success(), "{}", text(&result.stderr));
    for victim in &victims {
        assert_eq!(std::fs::read(victim).unwrap(), b"precious", "{} changed", victim.display());
    }
    for output in [&svg, &preview] {
        assert!(std::fs::symlink_metadata(output).unwrap().file_type().is_file(), "{}", output.display());
    }
    let left: Vec<String> = std::fs::read_dir(&shared)
        .unwrap()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|name| !std::fs::symlink_metadata(shared.join(name)).unwrap().file_type().is_symlink())
        .collect();
    assert_eq!(left.len(), 2, "only the two outputs are new files: {left:?}");
}

/// Waits (at most a minute) for a line of `lines` that holds `text`.
fn wait_for(lines: &Receiver<String>, text: &str) {
    common::testing::wait_for(lines, text, 60);
}

/// Whatever else `lines` holds, once the program ended.
fn rest(lines: Receiver<String>) -> String {
    lines.into_iter().collect::<Vec<_>>().join("\n")
}

/// Ctrl-C and SIGTERM during a long fine-tune write the best drawing so far and end with 130.
/// The signal goes once the program says which models it draws with: its work has begun.
#[test]
fn a_stopped_fine_tune_writes_its_best_drawing() {
    let fixture = Fixture::new("stop");
    for name in ["INT", "TERM"] {
        let svg = fixture.path(&format!("tuned-{name}.svg"));
        let photo = fixture.path("photo.png");
        let args =
            [photo.to_str().unwrap(), "-o", svg.to_str().unwrap(), "--paths", "20", "--finetune-secs", "600"];
        let mut child = spawn(&fixture, &args);
        let lines = stderr_lines(&mut child);
        wait_for(&lines, "models:");
        signal(&child, name);
        let result = wait_within(child, 60);
        assert_eq!(result.status.code(), Some(130), "{name}: {}", rest(lines));
        let drawn = std::fs::read_to_string(&svg).unwrap();
        resvg::usvg::Tree::from_str(&drawn, &resvg::usvg::Options::default()).expect("a whole SVG");
        assert!(drawn.matches("<path").count() >= 10, "{name}: {drawn}");
    }
    // Outside fine-tuning a stop ends the program at once, writing nothing (a picture that
    // takes seconds to segment, stopped in the middle).
    let (large, svg) = (fixture.path("large.png"), fixture.path("stopped.svg"));
    image::RgbImage::from_fn(1600, 1200, |x, y| {
        image::Rgb([(x * 7 % 251) as u8, (y * 13 % 253) as u8, ((x ^ y) % 255) as u8])
    })
    .save(&large)
    .unwrap();
    let args = [large.to_str().unwrap(), "-o", svg.to_str().unwrap(), "--size", "1600", "--paths", "8000"];
    let mut child = spawn(&fixture, &args);
    let lines = stderr_lines(&mut child);
    wait_for(&lines, "models:");
    signal(&child, "INT");
    let result = wait_within(child, 60);
    assert_eq!(result.status.code(), Some(130), "{}", rest(lines));
    assert!(!svg.exists());
}

/// One stop is one stop: `timeout` signals the program and then its process group, so a stop
/// arrives twice within moments; the second is not "again to abort", and the drawing is
/// written. Both go once fine-tuning has begun, the second 50 ms after the first, as
/// `timeout`'s two do (microseconds apart, delivered apart).
#[test]
fn one_stop_delivered_twice_still_writes_the_drawing() {
    let fixture = Fixture::new("twice");
    // A drawing whose steps and writing take a while, so the second delivery finds the program
    // still at work.
    let photo = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets/astronaut.jpg");
    for name in ["TERM", "INT"] {
        let svg = fixture.path(&format!("twice-{name}.svg"));
        let args = [
            photo.to_str().unwrap(),
            "-o",
            svg.to_str().unwrap(),
            "--paths",
            "2000",
            "--finetune-secs",
            "600",
        ];
        let mut child = spawn(&fixture, &args);
        let lines = stderr_lines(&mut child);
        wait_for(&lines, "fine-tuning");
        let pid = child.id();
        let twice = format!("kill -{name} {pid}; sleep 0.05; kill -{name} {pid} 2>/dev/null; true");
        assert!(Command::new("sh").args(["-c", &twice]).status().unwrap().success());
        let result = wait_within(child, 60);
        assert_eq!(result.status.code(), Some(130), "{name}: {}", rest(lines));
        let drawn = std::fs::read_to_string(&svg).unwrap_or_default();
        assert!(drawn.matches("<path").count() >= 10, "{name}: the drawing was lost: {drawn}");
    }
}

/// A stop in a job that fine-tunes, while a picture is still being drawn (a large one, at the
/// most paths), ends the program within moments: the drawings under way are not waited for
/// past the grace, nothing partial is left, and the program says so.
#[test]
fn a_stop_is_never_held_by_a_long_drawing() {
    let fixture = Fixture::new("held");
    let (large, svg) = (fixture.path("larger.png"), fixture.path("held.svg"));
    image::RgbImage::from_fn(4000, 3000, |x, y| {
        image::Rgb([(x * 7 % 251) as u8, (y * 13 % 253) as u8, ((x ^ y) % 255) as u8])
    })
    .save(&large)
    .unwrap();
    let args = [
        large.to_str().unwrap(),
        "-o",
        svg.to_str().unwrap(),
        "--size",
        "4000",
        "--paths",
        "20000",
        "--finetune-secs",
        "600",
    ];
    let mut child = spawn(&fixture, &args);
    let lines = stderr_lines(&mut child);
    wait_for(&lines, "models:");
    signal(&child, "TERM");
    let result = wait_within(child, 60);
    let said = rest(lines);
    assert_eq!(result.status.code(), Some(130), "{said}");
    assert!(said.contains("could not be written in time"), "the drawing ended first: {said}");
    let left: Vec<_> =
        std::fs::read_dir(fixture.path("")).unwrap().flatten().map(|e| e.file_name()).collect();
    assert!(!svg.exists() && !left.iter().any(|name| name.to_string_lossy().ends_with(".tmp")), "{left:?}");
}

/// stderr gone (closed after a line, or a full device) never ends the work: every SVG is
/// written and the status says the run went well.
#[test]
fn a_closed_or_full_stderr_never_stops_the_work() {
    let fixture = Fixture::new("stderr");
    let photo = fixture.path("photo.png");
    let inputs: Vec<String> = (0..6)
        .map(|i| {
            let copy = fixture.path(&format!("copy-{i}.png"));
            std::fs::copy(&photo, &copy).unwrap();
            copy.to_str().unwrap().to_string()
        })
        .collect();
    let out = fixture.path("out/");
    let mut args: Vec<&str> = inputs.iter().map(String::as_str).collect();
    args.extend(["-o", out.to_str().unwrap(), "--paths", "20", "--finetune-steps", "5"]);
    let mut child = spawn(&fixture, &args);
    let lines = stderr_lines(&mut child);
    wait_for(&lines, "models:");
    drop(lines);
    let result = wait_within(child, 120);
    assert!(result.status.success(), "{:?}", result.status);
    assert_eq!(std::fs::read_dir(&out).unwrap().count(), 6);

    let svg = fixture.path("full.svg");
    let result = Command::new(INFER)
        .args([photo.to_str().unwrap(), "-o", svg.to_str().unwrap(), "--paths", "20"])
        .args(["--coarse", fixture.path("coarse.ckpt").to_str().unwrap(), "--no-refine"])
        .stderr(std::fs::OpenOptions::new().write(true).open("/dev/full").unwrap())
        .status()
        .unwrap();
    assert!(result.success(), "{result:?}");
    assert!(svg.exists());
}

/// A named pipe that no program writes to, as the image or as a model, is refused at once as
/// an empty stream; a model given through a pipe (`<(cat coarse.ckpt)`) is read whole.
#[cfg(unix)]
#[test]
fn pipes_are_read_whole_and_never_waited_on() {
    let fixture = Fixture::new("fifo");
    let fifo = fixture.path("fifo");
    assert!(Command::new("mkfifo").arg(&fifo).status().unwrap().success());
    let (photo, svg) = (fixture.path("photo.png"), fixture.path("fifo.svg"));
    let (p, f, s) = (photo.to_str().unwrap(), fifo.to_str().unwrap(), svg.to_str().unwrap());
    for args in [vec![f, "-o", s], vec![p, "-o", s, "--coarse", f], vec![p, "-o", s, "--mover", f]] {
        let child = Command::new(INFER).args(&args).stderr(Stdio::piped()).spawn().unwrap();
        let result = wait_within(child, 60);
        let stderr = text(&result.stderr);
        assert_eq!(result.status.code(), Some(1), "{args:?}: {stderr}");
        assert!(stderr.contains("fifo") && stderr.contains("no program writes to"), "{args:?}: {stderr}");
    }
    let coarse = std::fs::read(fixture.path("coarse.ckpt")).unwrap();
    let mut child = Command::new(INFER)
        .args([p, "-o", s, "--paths", "20", "--coarse", "/dev/stdin", "--no-refine"])
        .stdin(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut stdin = child.stdin.take().unwrap();
    std::thread::spawn(move || std::io::Write::write_all(&mut stdin, &coarse));
    let result = wait_within(child, 60);
    assert!(result.status.success(), "{}", text(&result.stderr));
    assert!(text(&result.stderr).contains("coarse /dev/stdin (weights"), "{}", text(&result.stderr));
}

/// Peak resident memory of `child` in kB, sampled until it exits (VmHWM only grows), and how
/// many samples were read: a peak from no sample is no measurement.
fn peak_kb(mut child: Child) -> (u64, usize, std::process::ExitStatus) {
    let mut peak = 0;
    let mut samples = 0;
    loop {
        let status = std::fs::read_to_string(format!("/proc/{}/status", child.id())).unwrap_or_default();
        let hwm = status.lines().find(|l| l.starts_with("VmHWM:"));
        if let Some(kb) = hwm.and_then(|l| l.split_whitespace().nth(1)).and_then(|v| v.parse().ok()) {
            peak = peak.max(kb);
            samples += 1;
        }
        if let Some(status) = child.try_wait().unwrap() {
            return (peak, samples, status);
        }
        std::thread::sleep(Duration::from_millis(5));
    }
}

/// The peak resident memory (kB) of `infer INPUT -o SVG --paths PATHS` with the fixture's E_c
/// and no E_r, which must succeed and be sampled at least once.
#[cfg(target_os = "linux")]
fn peak_kb_of_infer(fixture: &Fixture, input: &Path, svg: &Path, paths: &str) -> u64 {
    let child = Command::new(INFER)
        .args([input.to_str().unwrap(), "-o", svg.to_str().unwrap(), "--paths", paths, "--quiet"])
        .args(["--coarse", fixture.path("coarse.ckpt").to_str().unwrap(), "--no-refine"])
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let (peak, samples, status) = peak_kb(child);
    assert!(status.success());
    assert!(samples > 0 && peak > 0, "no memory sample was read: {samples} samples, peak {peak} kB");
    peak
}

/// An 8192² 16-bit RGBA PNG is read into the working size without a copy at its own size.
#[cfg(target_os = "linux")]
#[test]
fn memory_follows_the_working_size_not_the_file() {
    let fixture = Fixture::new("memory");
    let big = fixture.path("big.png");
    let file = std::io::BufWriter::new(std::fs::File::create(&big).unwrap());
    let mut encoder = png::Encoder::new(file, 8192, 8192);
    encoder.set_color(png::ColorType::Rgba);
    encoder.set_depth(png::BitDepth::Sixteen);
    encoder.set_compression(png::Compression::Fastest);
    let mut writer = encoder.write_header().unwrap().into_stream_writer().unwrap();
    let row: Vec<u8> = (0..8192u32).flat_map(|x| [(x >> 5) as u8, 0, 40, 0, 200, 0, 255, 255]).collect();
    for _ in 0..8192 {
        std::io::Write::write_all(&mut writer, &row).unwrap();
    }
    writer.finish().unwrap();
    let svg = fixture.path("big.svg");
    let peak = peak_kb_of_infer(&fixture, &big, &svg, "20");
    assert!(std::fs::read_to_string(&svg).unwrap().contains("viewBox=\"0 0 8192 8192\""));
    assert!(peak <= 300 * 1024, "peak RSS {} MB", peak / 1024);
}

/// A 1 MB PNG whose ICC profile inflates to 600 MB is read in the memory of its pixels: the
/// profile is inflated only within a small limit, then dropped.
#[cfg(target_os = "linux")]
#[test]
fn a_png_profile_bomb_stays_small() {
    let fixture = Fixture::new("iccp");
    let bomb = fixture.path("bomb.png");
    let mut info = png::Info::with_size(64, 64);
    info.color_type = png::ColorType::Rgb;
    info.icc_profile = Some(vec![0u8; 600 << 20].into());
    let file = std::io::BufWriter::new(std::fs::File::create(&bomb).unwrap());
    let mut writer = png::Encoder::with_info(file, info).unwrap().write_header().unwrap();
    writer.write_image_data(&[90; 64 * 64 * 3]).unwrap();
    writer.finish().unwrap();
    assert!(std::fs::metadata(&bomb).unwrap().len() < 1 << 20);
    let svg = fixture.path("bomb.svg");
    let peak = peak_kb_of_infer(&fixture, &bomb, &svg, "4");
    assert!(svg.exists());
    assert!(peak <= 200 * 1024, "peak RSS {} MB", peak / 1024);
}

/// Inputs that cannot seek (a pipe, `/dev/stdin`), a folder or a device where a checkpoint
/// goes, an empty `SUPERSVG_MODELS`, a link to nothing as the output, two outputs on one file:
/// each works or is refused with a message that says what is wrong, before any output exists.
#[test]
fn misleading_inputs_get_messages_that_say_what_is_wrong() {
    let fixture = Fixture::new("messages");
    let photo = fixture.path("photo.png");
    let p = |name: &str| fixture.path(name).to_str().unwrap().to_string();

    // /dev/stdin as a file: read by streaming, not by seeking.
    let result = Command::new(INFER)
        .args([
            "/dev/stdin",
            "-o",
            &p("piped.svg"),
            "--paths",
            "10",
            "--coarse",
            &p("coarse.ckpt"),
            "--no-refine",
        ])
        .stdin(std::fs::File::open(&photo).unwrap())
        .output()
        .unwrap();
    assert!(result.status.success(), "{}", text(&result.stderr));
    assert!(fixture.path("piped.svg").exists());

    for (checkpoint, says) in
        [(fixture.path("").to_str().unwrap().to_string(), "is a folder"), ("/dev/null".into(), "/dev/null")]
    {
        let result = Command::new(INFER)
            .args([photo.to_str().unwrap(), "-o", &p("x.svg"), "--coarse", &checkpoint, "--no-refine"])
            .output()
            .unwrap();
        let stderr = text(&result.stderr);
        assert_eq!(result.status.code(), Some(1), "{stderr}");
        assert!(stderr.contains(says) && !stderr.contains("no such file"), "{stderr}");
    }

    // A model error leaves no output folder behind.
    let result = Command::new(INFER)
        .args([photo.to_str().unwrap(), "-o", &p("made/"), "--coarse", &p("nowhere.ckpt"), "--no-refine"])
        .output()
        .unwrap();
    assert_eq!(result.status.code(), Some(1));
    assert!(!fixture.path("made").exists(), "the output folder was created before the model failed");

    // SUPERSVG_MODELS set but empty is unset: the bundled models are found.
    let result = Command::new(INFER)
        .args([photo.to_str().unwrap(), "-o", &p("bundled.svg"), "--paths", "10", "--size", "64"])
        .env("SUPERSVG_MODELS", "")
        .output()
        .unwrap();
    assert!(result.status.success(), "{}", text(&result.stderr));

    #[cfg(unix)]
    {
        std::os::unix::fs::symlink(fixture.path("nowhere/out.svg"), fixture.path("dangling.svg")).unwrap();
        let result = fixture.infer(&[photo.to_str().unwrap(), "-o", &p("dangling.svg")]);
        assert_eq!(result.status.code(), Some(1));
        assert!(text(&result.stderr).contains("a link to nothing"), "{}", text(&result.stderr));
    }

    let result = fixture.infer(&[
        photo.to_str().unwrap(),
        "-o",
        &p("a.svg"),
        "--preview",
        &p("p.png"),
        "--compare",
        &p("p.png"),
    ]);
    let stderr = text(&result.stderr);
    assert!(stderr.contains("the --preview of") && stderr.contains("the --compare of"), "{stderr}");

    let result = fixture.infer(&[photo.to_str().unwrap(), "-o", &p("a.svg"), "--background", "+f+f+f"]);
    assert_eq!(result.status.code(), Some(2), "+f+f+f is no colour: {}", text(&result.stderr));
    let result =
        fixture.infer(&[photo.to_str().unwrap(), "-o", &p("a.svg"), "--finetune-steps", "1000000000"]);
    let stderr = text(&result.stderr);
    assert_eq!(result.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("--finetune-steps: 1000000000 steps: at most 100000"), "{stderr}");
}

/// `infer - -o - | head`: the reader leaving ends the program quietly.
#[test]
fn a_closed_pipe_ends_quietly() {
    let fixture = Fixture::new("pipe");
    let mut child = Command::new(INFER)
        .args(["-", "-o", "-", "--paths", "30", "--coarse", fixture.path("coarse.ckpt").to_str().unwrap()])
        .arg("--no-refine")
        .stdin(std::fs::File::open(fixture.path("photo.png")).unwrap())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take());
    let result = wait_within(child, 60);
    let stderr = text(&result.stderr);
    assert!(!stderr.contains("Broken pipe") && !stderr.contains("error"), "{stderr}");
}

/// A flat picture (and a fully transparent one) is one path, and the user is told why.
#[test]
fn flat_pictures_are_one_path() {
    let fixture = Fixture::new("flat");
    image::RgbImage::from_pixel(80, 60, image::Rgb([30, 120, 200])).save(fixture.path("flat.png")).unwrap();
    image::RgbaImage::from_pixel(80, 60, image::Rgba([30, 120, 200, 0]))
        .save(fixture.path("clear.png"))
        .unwrap();
    for name in ["flat", "clear"] {
        let (input, svg) = (fixture.path(&format!("{name}.png")), fixture.path(&format!("{name}.svg")));
        let result = fixture.infer(&[input.to_str().unwrap(), "-o", svg.to_str().unwrap(), "--paths", "500"]);
        assert!(result.status.success(), "{}", text(&result.stderr));
        assert_eq!(std::fs::read_to_string(&svg).unwrap().matches("<path").count(), 1, "{name}");
        assert!(text(&result.stderr).contains("1 of 500 paths drawn"), "{}", text(&result.stderr));
    }
}
