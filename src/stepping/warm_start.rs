//! What a step hands to the next: each contact's impulse (the solve's warm start) and, when the
//! solve coloured the contact graph (threaded or GPU Gauss–Seidel), each contact's colour, so
//! the next colouring is repaired rather than rebuilt, and the work list's neighbour table, the
//! threaded sweeps' blocks by colour and each body's contacts, reused while the contacts are the
//! same. Contacts are matched by (body, antagonist, feature).

use crate::detection::{Antagonist, DetectedContact};
use rayon::prelude::*;
use std::sync::Arc;

use crate::parallel::{filled, split_lengths, CHUNK};

use crate::problem::colouring::Colouring;
use crate::problem::matrix_free::{BlockColours, Incidence, MatrixFree, Neighbours};

pub(crate) type Key = (usize, Antagonist, u64);

/// A contact's key and impulse (normal, tangential, rolling; rolling 0 without rolling resistance).
pub(crate) type Entry = (Key, [f64; 3]);

/// Last step's impulses and colours, sorted by contact key.
#[derive(Default, Clone, Debug)]
pub struct WarmStart {
    entries: Vec<Entry>,
    /// Last step's colour of each entry, when its solve coloured the contact graph.
    colours: Option<Vec<u32>>,
    /// Last step's neighbour table, when its solve built one: it serves a step with the same
    /// contacts (the same keys in the same order).
    neighbours: Option<Arc<Neighbours>>,
    /// Last step's blocks by colour for the threaded sweeps, when its solve cut them: they serve
    /// a step with the same contacts, as the table does.
    block_colours: Option<Arc<BlockColours>>,
    /// Last step's contacts of each body, when built: they serve a step with the same contacts.
    incidence: Option<Arc<Incidence>>,
    /// Which bodies could move last step (empty when nothing above is kept): kept colours stay
    /// proper, and a kept table right, only while the same bodies move.
    moving: Vec<bool>,
    /// The time step the impulses were taken over (0: not known). An impulse is a force times
    /// the step, so a step of another length recalls them scaled to its own.
    time_step: f64,
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
    /// Last step's neighbour table, when its contacts were these and the same bodies move.
    pub neighbours: Option<Arc<Neighbours>>,
    /// Last step's blocks by colour, under the same conditions.
    pub block_colours: Option<Arc<BlockColours>>,
    /// Last step's contacts of each body, under the same conditions.
    pub incidence: Option<Arc<Incidence>>,
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
        self.neighbours = None;
        self.block_colours = None;
        self.incidence = None;
    }

    /// Remembers `impulses` (2 per contact, then 1 per contact with rolling resistance) of
    /// `contacts` (sorted by key, as detection returns them), taken over a step `h`, and the
    /// colouring and neighbour table the solve used on their operator `op`, if any, with the
    /// bodies that could move.
    pub fn remember(&mut self, contacts: &[DetectedContact], impulses: &[f64], op: Option<&MatrixFree>, h: f64) {
        self.entries.clear();
        self.time_step = h;
        let nc = contacts.len();
        let rolling = |a: usize| impulses.get(2 * nc + a).copied().unwrap_or(0.0);
        self.entries.par_extend(
            contacts
                .par_iter()
                .enumerate()
                .with_min_len(CHUNK)
                .map(|(a, c)| (c.key(), [impulses[2 * a], impulses[2 * a + 1], rolling(a)])),
        );
        debug_assert!(self.entries.windows(2).all(|w| w[0].0 <= w[1].0));
        self.colours = op.and_then(MatrixFree::colouring_if_built).map(Colouring::colour_of_each);
        self.neighbours = op.and_then(MatrixFree::neighbours_if_built);
        self.block_colours = op.and_then(MatrixFree::block_colours_if_built);
        self.incidence = op.and_then(MatrixFree::incidence_if_built);
        let kept = self.colours.is_some()
            || self.neighbours.is_some()
            || self.block_colours.is_some()
            || self.incidence.is_some();
        self.moving = match op {
            Some(op) if kept => op.moving(),
            _ => Vec::new(),
        };
    }

    /// What carries over to `contacts` (sorted by key) for a step `h`; `moving` says which
    /// bodies can move now, `rolling` whether the contacts have rolling unknowns.
    pub fn recall(&self, contacts: &[DetectedContact], moving: &[bool], rolling: bool, h: f64) -> Recalled {
        let nc = contacts.len();
        let mut impulses = filled(if rolling { 3 * nc } else { 2 * nc }, 0.0);
        let same_bodies = self.moving == moving;
        let colours = self.colours.as_ref().filter(|_| same_bodies);
        let mut kept = colours.map(|_| filled(nc, None));
        // An impulse is a force times the step: recalled at the new step's.
        let scale = if self.time_step > 0.0 && self.time_step != h { h / self.time_step } else { 1.0 };
        // Both lists are sorted by key: one merge, in chunks of contacts on threads, each chunk
        // writing its own share of the outputs.
        let chunks = Self::chunks_of(contacts);
        let width = |k: usize, on: bool| chunks.iter().map(move |&(first, end)| if on { k * (end - first) } else { 0 });
        let (sliding, rolls) = impulses.split_at_mut(2 * nc);
        let parts = (
            &chunks,
            split_lengths(sliding, width(2, true)),
            split_lengths(rolls, width(1, rolling)),
            split_lengths(kept.as_deref_mut().unwrap_or_default(), width(1, colours.is_some())),
        );
        let matched = parts
            .into_par_iter()
            .map(|(&(first, end), part, roll, kept_part)| {
                let mut e = self.entries.partition_point(|entry| entry.0 < contacts[first].key());
                let mut matched = 0;
                for (k, c) in contacts[first..end].iter().enumerate() {
                    let key = c.key();
                    while e < self.entries.len() && self.entries[e].0 < key {
                        e += 1;
                    }
                    if e < self.entries.len() && self.entries[e].0 == key {
                        let entry = &self.entries[e].1;
                        (part[2 * k], part[2 * k + 1]) = (entry[0] * scale, entry[1] * scale);
                        if let Some(r) = roll.get_mut(k) {
                            *r = entry[2] * scale;
                        }
                        if let (Some(kept), Some(colours)) = (kept_part.get_mut(k), colours) {
                            *kept = Some(colours[e]);
                        }
                        matched += 1;
                        // A key seen twice (two features alike) pairs up in order, never shares
                        // a colour.
                        e += 1;
                    }
                }
                matched
            })
            .sum::<usize>();
        // Every contact matched an entry and every entry a contact: the same keys in the same
        // order (the merge matches in increasing order), so the same bodies in each contact.
        let same_contacts = matched == nc && self.entries.len() == nc;
        let neighbours = self.neighbours.clone().filter(|_| same_contacts && same_bodies);
        let block_colours = self.block_colours.clone().filter(|_| same_contacts && same_bodies);
        let incidence = self.incidence.clone().filter(|_| same_contacts && same_bodies);
        Recalled { impulses, matched, colours: kept, neighbours, block_colours, incidence }
    }

    /// `contacts` (sorted by key) cut into chunks `[first, end)` of about [`CHUNK`] for a threaded
    /// merge with the entries, each chunk starting where the entries reach its first key. A chunk
    /// never splits a run of equal keys (two features alike): they pair up with their entries
    /// in order, so a key never matches twice.
    fn chunks_of(contacts: &[DetectedContact]) -> Vec<(usize, usize)> {
        let nc = contacts.len();
        let mut starts: Vec<usize> = (0..nc)
            .step_by(CHUNK)
            .map(|mut a| {
                while a > 0 && a < nc && contacts[a - 1].key() == contacts[a].key() {
                    a += 1;
                }
                a
            })
            .chain([nc])
            .collect();
        starts.dedup();
        starts.windows(2).map(|w| (w[0], w[1])).collect()
    }

    /// The entries (key and impulse, sorted by key): what a checkpoint saves, with
    /// [`Self::colours`].
    pub(crate) fn entries(&self) -> &[Entry] {
        &self.entries
    }

    /// Each entry's colour and the moving mask they were given with, if kept.
    pub(crate) fn colours(&self) -> Option<(&[u32], &[bool])> {
        self.colours.as_ref().map(|c| (c.as_slice(), self.moving.as_slice()))
    }

    /// The time step the impulses were taken over (0: not known).
    pub(crate) fn time_step(&self) -> f64 {
        self.time_step
    }

    /// The warm start [`Self::entries`] and [`Self::colours`] describe (entries sorted by key; one
    /// colour per entry), taken over a step `time_step` (0: not known, recalled unscaled).
    pub(crate) fn from_parts(entries: Vec<Entry>, colours: Option<(Vec<u32>, Vec<bool>)>, time_step: f64) -> Self {
        debug_assert!(entries.windows(2).all(|w| w[0].0 <= w[1].0));
        let (colours, moving) = match colours {
            Some((of_entry, moving)) => {
                debug_assert_eq!(of_entry.len(), entries.len());
                (Some(of_entry), moving)
            }
            None => (None, Vec::new()),
        };
        Self { entries, colours, neighbours: None, block_colours: None, incidence: None, moving, time_step }
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

#[cfg(test)]
mod tests {
    use glam::DVec2;

    use super::*;
    use crate::problem::matrix_free::disks_in_a_row;

    fn contact(i: usize, other: Antagonist) -> DetectedContact {
        let (point, normal, image) = (DVec2::ZERO, DVec2::Y, DVec2::ZERO);
        DetectedContact { i, other, feature: 0, point, normal, gap: 0.0, image }
    }

    /// Last step's neighbour table and blocks by colour serve the next step only when its
    /// contacts are the same keys in the same order and the same bodies move: a contact gone,
    /// one new, or a body pinned since, and they are built afresh.
    #[test]
    fn the_neighbour_table_and_blocks_carry_over_only_to_the_same_contacts_and_moving_bodies() {
        let op = disks_in_a_row();
        let contacts: Vec<DetectedContact> =
            vec![contact(0, Antagonist::Body(1)), contact(0, Antagonist::Wall(0)), contact(1, Antagonist::Wall(0))];
        let moving = op.moving();
        let mut warm = WarmStart::default();
        warm.remember(&contacts, &[0.0; 6], Some(&op), 1e-3);
        assert!(warm.recall(&contacts, &moving, false, 1e-3).neighbours.is_none(), "no table built, none kept");
        assert!(op.neighbours().tabled());
        let table = op.neighbours_if_built().expect("built");
        let blocks = op.block_colours_with(|_| Some(vec![vec![(0, 3)]])).expect("cut");
        let incidence = op.incidence_if_built().expect("built with the table");
        warm.remember(&contacts, &[0.0; 6], Some(&op), 1e-3);
        let recalled = warm.recall(&contacts, &moving, false, 1e-3);
        assert!(recalled.neighbours.is_some_and(|t| Arc::ptr_eq(&t, &table)));
        assert!(recalled.block_colours.is_some_and(|b| Arc::ptr_eq(&b, &blocks)));
        assert!(recalled.incidence.is_some_and(|i| Arc::ptr_eq(&i, &incidence)));
        assert!(warm.recall(&contacts[..2], &moving, false, 1e-3).incidence.is_none(), "a contact gone");
        assert!(warm.recall(&contacts[..2], &moving, false, 1e-3).neighbours.is_none(), "a contact gone");
        assert!(warm.recall(&contacts[..2], &moving, false, 1e-3).block_colours.is_none(), "a contact gone");
        let mut more = contacts.clone();
        more.push(contact(1, Antagonist::Wall(1)));
        assert!(warm.recall(&more, &moving, false, 1e-3).neighbours.is_none(), "a contact new");
        let mut pinned = moving.clone();
        pinned[1] = false;
        assert!(warm.recall(&contacts, &pinned, false, 1e-3).neighbours.is_none(), "a body pinned");
        assert!(warm.recall(&contacts, &pinned, false, 1e-3).block_colours.is_none(), "a body pinned");
        warm.forget_body(1);
        assert!(warm.recall(&contacts, &moving, false, 1e-3).neighbours.is_none(), "a body removed");
        assert!(warm.recall(&contacts, &moving, false, 1e-3).incidence.is_none(), "a body removed");
    }

    /// Recalled on threads in chunks of contacts, each contact gets the entry one merge of the
    /// two sorted lists gives it: the k-th contact of a key the k-th entry of that key, also
    /// where a run of equal keys (two features alike) straddles a chunk's start.
    #[test]
    fn impulses_and_colours_are_recalled_in_chunks_as_by_one_merge() {
        // Bodies 0..2,500 against a wall, body 1,022's contact four times over (contacts
        // 1,022-1,025, across the chunk that starts at 1,024); entries for the even bodies, two
        // for body 1,022, and some for bodies no contact has.
        let copies = |i: usize| if i == CHUNK - 2 { 4 } else { 1 };
        let contacts: Vec<DetectedContact> =
            (0..2_500).flat_map(|i| (0..copies(i)).map(move |_| contact(i, Antagonist::Wall(0)))).collect();
        let entry_copies = |i: usize| if i == CHUNK - 2 { 2 } else { usize::from(i.is_multiple_of(2)) };
        let keys: Vec<Key> = (0..3_000)
            .step_by(1)
            .flat_map(|i| (0..entry_copies(i)).map(move |_| (i, Antagonist::Wall(0), 0)))
            .collect();
        let entries: Vec<Entry> =
            keys.iter().enumerate().map(|(e, &k)| (k, [e as f64, 0.5 * e as f64, -(e as f64)])).collect();
        let colours: Vec<u32> = (0..entries.len() as u32).map(|e| e % 7).collect();
        let warm = WarmStart::from_parts(entries.clone(), Some((colours.clone(), vec![true; 3_000])), 1e-3);
        let pool = rayon::ThreadPoolBuilder::new().num_threads(4).build().unwrap();
        let recalled = pool.install(|| warm.recall(&contacts, &[true; 3_000], true, 1e-3));
        // The reference: the k-th contact of a key takes the k-th entry of that key.
        let mut seen = std::collections::HashMap::new();
        let nc = contacts.len();
        let mut matched = 0;
        for (a, c) in contacts.iter().enumerate() {
            let k = seen.entry(c.key()).or_insert(0);
            let entry = keys.iter().enumerate().filter(|(_, &key)| key == c.key()).nth(*k).map(|(e, _)| e);
            *k += 1;
            let (want, colour) = match entry {
                Some(e) => (entries[e].1, Some(colours[e])),
                None => ([0.0; 3], None),
            };
            matched += usize::from(entry.is_some());
            let got = [recalled.impulses[2 * a], recalled.impulses[2 * a + 1], recalled.impulses[2 * nc + a]];
            assert_eq!(got, want, "contact {a} of body {}", c.i);
            assert_eq!(recalled.colours.as_ref().unwrap()[a], colour, "contact {a}'s colour");
        }
        assert_eq!(recalled.matched, matched);
        assert_eq!(matched, 1_250 + 1, "the even bodies' contacts and body 1,022's second");
    }

    /// An impulse is a force times the step: a step of another length starts from last step's
    /// impulses scaled to it, rolling ones too; the same step recalls them bit for bit.
    #[test]
    fn impulses_are_recalled_scaled_to_the_step() {
        let contacts = vec![contact(0, Antagonist::Body(1)), contact(1, Antagonist::Wall(0))];
        let impulses = [0.3, -0.1, 0.7 / 3.0, 0.05, 1e-3, 2e-3];
        let mut warm = WarmStart::default();
        warm.remember(&contacts, &impulses, None, 1e-3);
        assert_eq!(warm.recall(&contacts, &[true; 2], true, 1e-3).impulses, impulses);
        let halved = warm.recall(&contacts, &[true; 2], true, 5e-4).impulses;
        for (a, b) in halved.iter().zip(impulses) {
            assert!((a - b / 2.0).abs() <= 1e-15 * b.abs(), "{a} against {b} / 2");
        }
        let unknown = WarmStart::from_parts(warm.entries().to_vec(), None, 0.0);
        assert_eq!(unknown.recall(&contacts, &[true; 2], true, 5e-4).impulses, impulses, "a step not known");
    }
}
