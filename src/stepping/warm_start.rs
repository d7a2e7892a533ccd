//! Carries each contact's impulse to the next step: contacts are matched by (body, antagonist,
//! feature), so a solve starts from last step's answer.

use crate::detection::{Antagonist, DetectedContact};

type Key = (usize, Antagonist, u64);

/// Last step's impulses, sorted by contact key.
#[derive(Default, Clone, Debug)]
pub struct WarmStart {
    entries: Vec<(Key, [f64; 2])>,
}

impl WarmStart {
    /// Remembers `impulses` (2 per contact) of `contacts` (sorted by key, as detection returns them).
    pub fn remember(&mut self, contacts: &[DetectedContact], impulses: &[f64]) {
        self.entries.clear();
        self.entries
            .extend(contacts.iter().enumerate().map(|(a, c)| (c.key(), [impulses[2 * a], impulses[2 * a + 1]])));
        debug_assert!(self.entries.windows(2).all(|w| w[0].0 <= w[1].0));
    }

    /// Initial impulses for `contacts`, and how many were found in last step's set.
    pub fn initial_impulses(&self, contacts: &[DetectedContact]) -> (Vec<f64>, usize) {
        let mut r = vec![0.0; 2 * contacts.len()];
        let mut matched = 0;
        for (a, c) in contacts.iter().enumerate() {
            if let Ok(k) = self.entries.binary_search_by(|e| e.0.cmp(&c.key())) {
                r[2 * a] = self.entries[k].1[0];
                r[2 * a + 1] = self.entries[k].1[1];
                matched += 1;
            }
        }
        (r, matched)
    }

    pub fn len(&self) -> usize {
        self.entries.len()
    }

    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }
}
