//! Samples that arrive a beam at a time, gathered into batches for a
//! driver: one beam's rays are too few for the store to sort them or to
//! project them on every core.

use crate::{Driver, Sample};

/// Samples gathered before the driver takes them together.
pub const GATHER: usize = 1 << 17;

/// Samples received and not yet handed to a driver.
#[derive(Debug, Default)]
pub struct Gather {
    batch: Vec<Sample>,
}

impl Gather {
    /// Adds `samples`, handing the batch to `driver` once it holds
    /// [`GATHER`].
    pub fn add(&mut self, samples: &[Sample], driver: &mut dyn Driver) {
        self.batch.extend_from_slice(samples);
        if self.batch.len() >= GATHER {
            self.flush(driver);
        }
    }

    /// Hands what is gathered to `driver`: before drawing, and before
    /// anything else reaches the driver, so that rays keep their order.
    pub fn flush(&mut self, driver: &mut dyn Driver) {
        if !self.batch.is_empty() {
            driver.add(&self.batch);
            self.batch.clear();
        }
    }
}
