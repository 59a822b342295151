//! Batches made ahead of the model on worker threads, delivered in stream order.

use std::sync::Arc;
use std::sync::mpsc::{Receiver, sync_channel};

use super::source::{Batch, DataError, DataSource};

/// Prepares batches `first, first + 1, …` on `workers` threads (batch i on worker i mod workers),
/// keeping up to `prefetch` batches ready per worker. The order never depends on thread timing.
pub struct Loader {
    receivers: Vec<Receiver<Result<Batch, DataError>>>,
    next: u64,
}

impl Loader {
    /// Starts the workers.
    pub fn start(source: Arc<DataSource>, first: u64, workers: usize, prefetch: usize) -> Self {
        let workers = workers.max(1) as u64;
        let receivers = (0..workers)
            .map(|worker| {
                let (sender, receiver) = sync_channel(prefetch.max(1));
                let source = Arc::clone(&source);
                std::thread::Builder::new()
                    .name(format!("data-{worker}"))
                    .spawn(move || {
                        let mut index = first + (worker + workers - first % workers) % workers;
                        // Ends when the loader is dropped and the channel closes, or after
                        // delivering an error.
                        loop {
                            let batch = source.batch(index);
                            let failed = batch.is_err();
                            if sender.send(batch).is_err() || failed {
                                break;
                            }
                            index += workers;
                        }
                    })
                    .expect("a data thread starts");
                receiver
            })
            .collect();
        Self { receivers, next: first }
    }

    /// The next batch of the stream, waiting for it if needed.
    pub fn next_batch(&mut self) -> Result<Batch, DataError> {
        let worker = (self.next % self.receivers.len() as u64) as usize;
        let batch = self.receivers[worker].recv().map_err(|_| DataError::WorkerStopped(self.next))??;
        debug_assert_eq!(batch.index, self.next);
        self.next += 1;
        Ok(batch)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::DataConfig;

    #[test]
    fn delivers_the_stream_in_order_from_any_start() {
        let config = DataConfig { image_size: 48, segments: [3, 6], ..Default::default() };
        let model = model::ModelConfig { input_size: 8, ..model::ModelConfig::preset(model::Preset::Cpu) };
        let source = Arc::new(DataSource::new(&config, &model, 2, 1).unwrap());
        let mut loader = Loader::start(Arc::clone(&source), 5, 3, 2);
        for index in 5..12 {
            assert_eq!(loader.next_batch().unwrap(), source.batch(index).unwrap());
        }
    }
}
