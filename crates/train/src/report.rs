//! What a running training shows: a progress bar (or plain lines off a terminal) and
//! `metrics.jsonl`.

use std::fs::{File, OpenOptions};
use std::io::Write;
use std::path::Path;

use common::progress::Bar;
use serde::Serialize;
use serde_json::{Map, Value};

use crate::inference::AtInference;
use crate::validation::Scores;

/// One logged step.
pub struct StepRecord {
    /// Steps completed.
    pub step: usize,
    /// Learning rate used.
    pub lr: f64,
    /// The total loss.
    pub loss: f32,
    /// Every loss term and weight by name.
    pub values: Vec<(&'static str, f32)>,
    /// Wall seconds of the step.
    pub seconds: f64,
    /// Of which waiting for data.
    pub data_seconds: f64,
    /// Samples per second over the step.
    pub samples_per_second: f64,
}

/// Cuts the metrics file at `path` back to its whole lines of steps up to `start`: a run killed
/// after its last checkpoint (`kill -9`, a power cut) logged steps that the resumed run takes
/// again, and maybe half a line; each step then appears once.
fn cut_back(path: &Path, start: usize) -> std::io::Result<()> {
    let text = match std::fs::read_to_string(path) {
        Err(err) if err.kind() == std::io::ErrorKind::NotFound => return Ok(()),
        read => read?,
    };
    let step = |line: &str| serde_json::from_str::<Value>(line).ok()?.get("step")?.as_u64();
    let kept: String = text
        .split_inclusive('\n')
        .filter(|line| line.ends_with('\n') && step(line).is_some_and(|step| step <= start as u64))
        .collect();
    if kept.len() == text.len() {
        return Ok(());
    }
    common::write::write_atomic(path, kept.as_bytes())
}

/// Progress display and the metrics file.
pub struct Reporter {
    bar: Bar,
    metrics: File,
    total: usize,
}

impl Reporter {
    /// Opens `dir/metrics.jsonl` — started again when `fresh`, continued otherwise (a resumed
    /// run, from its lines up to step `start`) — and shows progress from `start` to `total` steps.
    pub fn open(dir: &Path, start: usize, total: usize, fresh: bool) -> std::io::Result<Self> {
        let path = dir.join("metrics.jsonl");
        let metrics = if fresh {
            OpenOptions::new().create(true).write(true).truncate(true).open(path)?
        } else {
            cut_back(&path, start)?;
            OpenOptions::new().create(true).append(true).open(path)?
        };
        let bar = Bar::new("", total as u64, "steps", true);
        bar.set_position(start as u64);
        Ok(Self { bar, metrics, total })
    }

    /// Records a step: a JSON line in the metrics file, and the progress display.
    pub fn record(&mut self, record: &StepRecord) -> std::io::Result<()> {
        let mut line = Map::new();
        line.insert("step".into(), record.step.into());
        line.insert("loss".into(), f64::from(record.loss).into());
        for (name, value) in &record.values {
            line.insert((*name).into(), f64::from(*value).into());
        }
        line.insert("lr".into(), record.lr.into());
        line.insert("seconds_per_step".into(), record.seconds.into());
        line.insert("data_seconds".into(), record.data_seconds.into());
        line.insert("samples_per_second".into(), record.samples_per_second.into());
        writeln!(self.metrics, "{}", Value::Object(line))?;

        let terms: Vec<String> =
            record.values.iter().map(|(name, value)| format!("{name} {value:.4}")).collect();
        let message = format!(
            "loss {:.5} | {} | lr {:.2e} | {:.1} samples/s",
            record.loss,
            terms.join(" "),
            record.lr,
            record.samples_per_second
        );
        if self.bar.is_shown() {
            self.bar.set_position(record.step as u64);
            self.bar.set_message(message);
        } else {
            common::say!("step {}/{} {message}", record.step, self.total);
        }
        Ok(())
    }

    /// Records validation scores at `step`: a JSON line of `val_*` values in the metrics file,
    /// and a line on the display.
    pub fn validation(&mut self, step: usize, scores: &Scores) -> std::io::Result<()> {
        self.scores_line(step, "val_", scores)?;
        self.say(&format!(
            "validation at step {step}: {:.2} dB kept ({:+.2} over the flat fill, {:.1} paths kept of {:.1}), \
             {:.2} dB all drawn, spill {:.3}",
            scores.psnr_kept,
            scores.psnr_kept - scores.psnr_flat,
            scores.kept,
            scores.visible,
            scores.psnr_drawn,
            scores.spill
        ));
        Ok(())
    }

    /// Records a network's scores at inference at `step`: a JSON line of `val_coarse_*` or
    /// `val_refine_*` values, and a line on the display.
    pub fn at_inference(&mut self, step: usize, scores: &AtInference) -> std::io::Result<()> {
        match scores {
            AtInference::Coarse(scores) => {
                self.scores_line(step, "val_coarse_", scores)?;
                self.say(&format!(
                    "at inference: B {:.3} dB with {} E_c paths, the regions alone {:.3} dB ({:+.3})",
                    scores.psnr_b,
                    scores.bought,
                    scores.psnr_regions,
                    scores.margin_db()
                ));
            }
            AtInference::Refine(scores) => {
                self.scores_line(step, "val_refine_", scores)?;
                self.say(&format!(
                    "at inference: E_r kept {} of {} paths, +{:.3} dB, where as many more regions add +{:.3} dB ({:+.3}) \
                     and the optimizer in E_r's place +{:.3}",
                    scores.kept,
                    scores.proposed,
                    scores.gain_db,
                    scores.regions_db,
                    scores.margin_db(),
                    scores.optimizer_db
                ));
            }
        }
        Ok(())
    }

    /// A metrics line of `step` and every field of `scores` (a struct) named `prefix` + field.
    fn scores_line(&mut self, step: usize, prefix: &str, scores: &impl Serialize) -> std::io::Result<()> {
        let mut line = Map::new();
        line.insert("step".into(), step.into());
        let values = serde_json::to_value(scores).expect("scores serialize");
        for (name, value) in values.as_object().expect("scores are a struct") {
            line.insert(format!("{prefix}{name}"), value.clone());
        }
        writeln!(self.metrics, "{}", Value::Object(line))
    }

    /// Prints a line without breaking the progress bar.
    pub fn say(&self, message: &str) {
        self.bar.println(message);
    }

    /// Removes the progress bar.
    pub fn finish(&self) {
        self.bar.finish();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_resumed_run_logs_each_step_once() {
        let dir = std::env::temp_dir().join(format!("supersvg-report-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let record = |step| StepRecord {
            step,
            lr: 1e-3,
            loss: 0.5,
            values: vec![("l2", 0.5)],
            seconds: 0.1,
            data_seconds: 0.0,
            samples_per_second: 10.0,
        };
        let steps = || -> Vec<u64> {
            let text = std::fs::read_to_string(dir.join("metrics.jsonl")).unwrap();
            text.lines()
                .map(|line| serde_json::from_str::<Value>(line).unwrap()["step"].as_u64().unwrap())
                .collect()
        };
        let mut reporter = Reporter::open(&dir, 0, 10, true).unwrap();
        (1..=5).for_each(|step| reporter.record(&record(step)).unwrap());
        drop(reporter);
        // Killed after step 5 with its checkpoint at step 3, mid-way through a line.
        let mut file = OpenOptions::new().append(true).open(dir.join("metrics.jsonl")).unwrap();
        file.write_all(b"{\"step\": 6, \"lo").unwrap();
        let mut reporter = Reporter::open(&dir, 3, 10, false).unwrap();
        assert_eq!(steps(), [1, 2, 3]);
        (4..=6).for_each(|step| reporter.record(&record(step)).unwrap());
        assert_eq!(steps(), [1, 2, 3, 4, 5, 6]);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
