//! Training samples: superpixel crops of generated scenes and of image folders, built on worker
//! threads, in an order fixed by the seed alone.

mod images;
mod loader;
mod source;
mod synthetic;

pub use images::ImageSet;
pub use loader::Loader;
pub use source::{Batch, DataError, DataSource, DrawnBox, DrawnBoxes, Samples};
pub use synthetic::synthetic_scene;
