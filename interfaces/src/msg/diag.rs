//! Component diagnostics: the counters every component publishes (drops by reason, restarts...).

use crate::header::Header;
use serde::{Deserialize, Serialize};

/// One named counter.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Counter {
    pub name: String,
    pub value: u64,
}

/// A component's counters, published periodically on [`crate::topics::DIAGNOSTICS`].
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Diagnostics {
    pub header: Header,
    pub component: String,
    pub counters: Vec<Counter>,
}

impl Diagnostics {
    /// The value of counter `name`, 0 when absent.
    pub fn get(&self, name: &str) -> u64 {
        self.counters
            .iter()
            .find(|c| c.name == name)
            .map_or(0, |c| c.value)
    }
}
