//! What a step hands to the next: each contact's impulse (the solve's warm start) and, when the
//! solve coloured the contact graph (threaded or GPU Gauss–Seidel), each contact's colour, so
//! the next colouring is repaired rather than rebuilt. Contacts are matched by (body,
//! antagonist, feature).

use crate::detection::{Antagonist, DetectedContact};
use crate::problem::colouring::Colouring;

pub(crate) type Key = (usize, Antagonist, u64);

/// A contact's key and impulse (normal, tangential, rolling; rolling 0 without rolling resistance).
pub(crate) type Entry = (Key, [f64; 3]);

/// Last step's impulses and colours, sorted by contact key.
#[derive(Default, Clone, Debug)]
pub struct WarmStart {
    entries: Vec<Entry>,
    colours: Option<Colours>,
}

/// Last step's colour of each entry, and which bodies could move then: kept colours stay
/// proper only while the same bodies move.
#[derive(Clone, Debug)]
struct Colours {
    of_entry: Vec<u32>,
    moving: Vec<bool>,
}

/// What the last step carries over to `contacts`.
pub struct Recalled {
    /// Initial impulses, 2 per contact then 1 per contact with rolling (zero for a new contact).
    pub impulses: Vec<f64>,
    /// How many contacts were found in last step's set.
    pub matched: usize,
    /// Last step's colour of each contact (`None`: new), when last step's solve coloured its
    /// graph and the same bodies move.
    pub colours: Option<Vec<Option<u32>>>,
}

/// `key` after body `removed` is removed: `None` when it involves that body, else with the
/// indices above it moved down one (the order of keys is kept).
pub(crate) fn key_without_body(key: Key, removed: usize) -> Option<Key> {
    let shift = |b: usize| if b > removed { b - 1 } else { b };
    let other = match key.1 {
        Antagonist::Body(j) if j == removed => return None,
        Antagonist::Body(j) => Antagonist::Body(shift(j)),
        wall => wall,
    };
    (key.0 != removed).then(|| (shift(key.0), other, key.2))
}

impl WarmStart {
    /// Forgets the contacts of body `k` and renumbers the rest as `key_without_body` does; the
    /// colours are dropped (the next colouring is built afresh).
    pub fn forget_body(&mut self, k: usize) {
        self.entries = std::mem::take(&mut self.entries)
            .into_iter()
            .filter_map(|(key, r)| key_without_body(key, k).map(|key| (key, r)))
            .collect();
        self.colours = None;
    }

    /// Remembers `impulses` (2 per contact, then 1 per contact with rolling resistance) of
    /// `contacts` (sorted by key, as detection returns them), and the colouring the solve used,
    /// if any, with the bodies that could move.
    pub fn remember(
        &mut self,
        contacts: &[DetectedContact],
        impulses: &[f64],
        colouring: Option<(&Colouring, Vec<bool>)>,
    ) {
        self.entries.clear();
        let nc = contacts.len();
        let rolling = |a: usize| impulses.get(2 * nc + a).copied().unwrap_or(0.0);
        self.entries.extend(
            contacts.iter().enumerate().map(|(a, c)| (c.key(), [impulses[2 * a], impulses[2 * a + 1], rolling(a)])),
        );
        debug_assert!(self.entries.windows(2).all(|w| w[0].0 <= w[1].0));
        self.colours = colouring.map(|(c, moving)| Colours { of_entry: c.colour_of_each(), moving });
    }

    /// What carries over to `contacts` (sorted by key); `moving` says which bodies can move now,
    /// `rolling` whether the contacts have rolling unknowns.
    pub fn recall(&self, contacts: &[DetectedContact], moving: &[bool], rolling: bool) -> Recalled {
        let nc = contacts.len();
        let mut impulses = vec![0.0; if rolling { 3 * nc } else { 2 * nc }];
        let colours = self.colours.as_ref().filter(|c| c.moving == moving);
        let mut kept = colours.map(|_| vec![None; contacts.len()]);
        let mut matched = 0;
        // Both lists are sorted by key: one merge.
        let mut e = 0;
        for (a, c) in contacts.iter().enumerate() {
            let key = c.key();
            while e < self.entries.len() && self.entries[e].0 < key {
                e += 1;
            }
            if e < self.entries.len() && self.entries[e].0 == key {
                impulses[2 * a] = self.entries[e].1[0];
                impulses[2 * a + 1] = self.entries[e].1[1];
                if rolling {
                    impulses[2 * nc + a] = self.entries[e].1[2];
                }
                if let (Some(kept), Some(colours)) = (kept.as_mut(), colours) {
                    kept[a] = Some(colours.of_entry[e]);
                }
                matched += 1;
                // A key seen twice (two features alike) pairs up in order, never shares a colour.
                e += 1;
            }
        }
        Recalled { impulses, matched, colours: kept }
    }

    /// The entries (key and impulse, sorted by key): what a checkpoint saves, with
    /// [`Self::colours`].
    pub(crate) fn entries(&self) -> &[Entry] {
        &self.entries
    }

    /// Each entry's colour and the moving mask they were given with, if kept.
    pub(crate) fn colours(&self) -> Option<(&[u32], &[bool])> {
        self.colours.as_ref().map(|c| (c.of_entry.as_slice(), c.moving.as_slice()))
    }

    /// The warm start [`Self::entries`] and [`Self::colours`] describe (entries sorted by key; one colour per entry).
    pub(crate) fn from_parts(entries: Vec<Entry>, colours: Option<(Vec<u32>, Vec<bool>)>) -> Self {
        debug_assert!(entries.windows(2).all(|w| w[0].0 <= w[1].0));
        let colours = colours.map(|(of_entry, moving)| {
            debug_assert_eq!(of_entry.len(), entries.len());
            Colours { of_entry, moving }
        });
        Self { entries, colours }
    }

    /// Contacts remembered.
    pub fn len(&self) -> usize {
        self.entries.len()
    }

    /// Whether none is remembered.
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }
}
