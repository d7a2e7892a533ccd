//! Matrix-free Delassus operator `W = B M⁻¹ Bᵀ` from bodies and contacts.
//!
//! A product never forms `W`: it scatters impulses to body velocities (`M⁻¹ Bᵀ r`) and gathers
//! them back at the contacts (`B v`), in O(contacts + bodies).

use std::sync::atomic::{AtomicBool, Ordering::Relaxed};
use std::sync::{Arc, OnceLock};

use rayon::iter::Either;
use rayon::prelude::*;

use super::colouring::Colouring;
use super::{BlockSparse, Mat2};
use crate::parallel::{fill_and_sum, filled, first_failure, map_indices, parallel, CHUNK};

/// Contact ranges `(first, end)` by colour: blocks of one colour share no moving body.
pub type BlockColours = Vec<Vec<(usize, usize)>>;

/// A rigid body's inverse mass and inverse inertia. A static body (a wall) has both zero; a body
/// that holds its velocity along an axis is marked by [`MatrixFree::with_held_axes`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Body {
    /// 1/m (0: fixed).
    pub inv_mass: f64,
    /// 1/I (0: fixed or not turning).
    pub inv_inertia: f64,
}

impl Body {
    /// A moving body of this mass and inertia (inertia 0 or infinite: it does not turn).
    pub fn dynamic(mass: f64, inertia: f64) -> Self {
        Self {
            inv_mass: 1.0 / mass,
            inv_inertia: if inertia > 0.0 && inertia.is_finite() { 1.0 / inertia } else { 0.0 },
        }
    }
    /// A fixed body (a wall, a support).
    pub fn fixed() -> Self {
        Self { inv_mass: 0.0, inv_inertia: 0.0 }
    }
}

/// A contact between body `i` (candidate) and body `j` (antagonist, `None` for a fixed obstacle).
/// `normal` points from j to i (positive normal velocity = separation); `lever_*` are the vectors
/// from each body's centre of mass to the contact point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Contact {
    /// The candidate body.
    pub i: usize,
    /// The antagonist body, `None` for a fixed obstacle.
    pub j: Option<usize>,
    /// Unit normal from j to i.
    pub normal: [f64; 2],
    /// From i's centre of mass to the contact point.
    pub lever_i: [f64; 2],
    /// From j's centre of mass to the contact point.
    pub lever_j: [f64; 2],
}

/// Which generalised velocities and contact rows exist. An effect that is off costs nothing:
/// without rotation bodies carry two dofs and contacts store no lever arms; without friction the
/// tangential row of a contact is never gathered or scattered (`u_t ≡ 0`, `r_t ≡ 0`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Dofs {
    /// Bodies turn (a spin per body, lever arms per contact).
    pub rotation: bool,
    /// Contacts have a tangential row.
    pub friction: bool,
}

impl Dofs {
    /// Every dof: rotation and friction.
    pub const ALL: Dofs = Dofs { rotation: true, friction: true };

    /// Generalised velocities per body: (v_x, v_y, ω) or (v_x, v_y).
    pub fn per_body(self) -> usize {
        if self.rotation {
            3
        } else {
            2
        }
    }
}

/// Precomputed rows of `B` for one contact: body i gets `+[e_x, e_y, ρ_i×e]`, body j `−[e_x, e_y, ρ_j×e]`.
/// The rotational parts `ρ×e` live in a separate array that exists only when rotation is on.
#[derive(Clone, Copy, Debug)]
pub(crate) struct ContactRows {
    pub(crate) i: usize,
    pub(crate) j: usize, // NO_BODY when the antagonist is fixed
    pub(crate) n: [f64; 2],
}

/// Where a product keeps body velocities: a plain slice, or [`SharedSlice`] for a threaded
/// Gauss–Seidel sweep.
pub(crate) trait Velocities {
    fn get(&self, k: usize) -> f64;
    fn add(&mut self, k: usize, x: f64);
}

impl Velocities for [f64] {
    #[inline]
    fn get(&self, k: usize) -> f64 {
        self[k]
    }
    #[inline]
    fn add(&mut self, k: usize, x: f64) {
        self[k] += x;
    }
}

/// A slice (body velocities, impulses) written by several threads at once, each to places no
/// other thread touches (the contacts of one colour share no moving body, and fixed bodies are
/// never written).
#[derive(Clone, Copy)]
pub(crate) struct SharedSlice {
    ptr: *mut f64,
    len: usize,
}

// SAFETY: used only within one colour of a proper colouring, where no two contacts touch the
// same moving body: every element is read and written by one thread at a time.
unsafe impl Send for SharedSlice {}
unsafe impl Sync for SharedSlice {}

impl SharedSlice {
    pub(crate) fn new(v: &mut [f64]) -> Self {
        Self { ptr: v.as_mut_ptr(), len: v.len() }
    }
}

impl SharedSlice {
    /// Element `k`'s address, for a prefetch hint (not to be read through).
    #[inline]
    pub(crate) fn address(&self, k: usize) -> *const f64 {
        self.ptr.wrapping_add(k)
    }

    #[inline]
    pub(crate) fn set(&mut self, k: usize, x: f64) {
        debug_assert!(k < self.len);
        // SAFETY: as in `get`.
        unsafe { *self.ptr.add(k) = x }
    }
}

impl Velocities for SharedSlice {
    #[inline]
    fn get(&self, k: usize) -> f64 {
        // In bounds: body and contact indices are checked when the operator is built.
        debug_assert!(k < self.len);
        // SAFETY: in bounds; no other thread writes element k during this colour (see above).
        unsafe { *self.ptr.add(k) }
    }
    #[inline]
    fn add(&mut self, k: usize, x: f64) {
        debug_assert!(k < self.len);
        // SAFETY: as in `get`.
        unsafe { *self.ptr.add(k) += x }
    }
}

/// `(ρ_i × n, ρ_i × t, ρ_j × n, ρ_j × t)`.
pub(crate) type Levers = [f64; 4];

pub(crate) const NO_BODY: usize = usize::MAX;

/// `W = B M⁻¹ Bᵀ` kept as its bodies and contact rows, never assembled.
#[derive(Clone, Debug)]
pub struct MatrixFree {
    pub(crate) bodies: Vec<Body>,
    pub(crate) rows: Vec<ContactRows>,
    /// Empty without rotation.
    pub(crate) levers: Vec<Levers>,
    pub(crate) dofs: Dofs,
    /// Each body's contacts, built on first use (threaded products, colouring) or handed in with
    /// the neighbour table; shared like it.
    incidence: OnceLock<Arc<Incidence>>,
    /// Each contact's neighbours, built on first use (work lists) or handed in (last step's, when
    /// the contact graph is the same); shared, to keep the operator small and the hand-over free.
    neighbours: OnceLock<Option<Arc<Neighbours>>>,
    /// The threaded sweeps' blocks by colour, built on first use or handed in with the neighbour
    /// table (the same contacts, the same moving bodies).
    block_colours: OnceLock<Option<Arc<BlockColours>>>,
    /// The contact graph's colouring, built on first use or handed in (repaired from the
    /// last step's by the stepping).
    colouring: OnceLock<Colouring>,
    /// The diagonal blocks `W_αα`, built once (a solve and its stopping test both read them).
    diag: OnceLock<Vec<Mat2>>,
    /// Each contact's rolling radius when rolling resistance is on (empty when off): the
    /// rolling row `u_r = R (ω_i − ω_j)` follows the (n, t) rows, its impulse `r_r` is a torque
    /// impulse `R r_r` on i and `−R r_r` on j.
    rolling_radius: Vec<f64>,
    /// The axes (x, y) along which each body holds its velocity, its inverse mass there taken as
    /// zero; empty when none does (a body kept in 16 bytes: with 24, the 10,000-disk pile's step
    /// took 1-6 % longer; this table about 1 %).
    held: Vec<[bool; 2]>,
}

/// The contacts of each body in increasing contact order, with the side the body is on: a
/// body's velocity summed over this list adds the same terms in the same order as the
/// sequential scatter, so threaded and sequential products agree to the bit.
#[derive(Clone, Debug, PartialEq)]
pub struct Incidence {
    start: Vec<usize>,
    /// `(contact, body is the antagonist j)`.
    list: Vec<(usize, bool)>,
}

impl Incidence {
    fn new(n_bodies: usize, rows: &[ContactRows]) -> Self {
        let mut start = vec![0usize; n_bodies + 1];
        for c in rows {
            start[c.i + 1] += 1;
            if c.j != NO_BODY {
                start[c.j + 1] += 1;
            }
        }
        for k in 0..n_bodies {
            start[k + 1] += start[k];
        }
        let mut fill = start.clone();
        let mut list = vec![(0, false); start[n_bodies]];
        for (a, c) in rows.iter().enumerate() {
            list[fill[c.i]] = (a, false);
            fill[c.i] += 1;
            if c.j != NO_BODY {
                list[fill[c.j]] = (a, true);
                fill[c.j] += 1;
            }
        }
        Self { start, list }
    }

    /// Contacts touching body `k`, in increasing order.
    pub fn contacts_of(&self, k: usize) -> impl Iterator<Item = usize> + '_ {
        self.list[self.start[k]..self.start[k + 1]].iter().map(|&(a, _)| a)
    }
}

/// Each contact's neighbours: the contacts of its moving bodies (itself included), body `i`'s
/// before body `j`'s, each in increasing order and listed once. A work list wakes a contact's
/// neighbours after each update; one short row of indices costs fewer cache misses than the
/// bodies' two lists of [`Incidence`].
#[derive(Clone, Debug, PartialEq)]
pub struct Neighbours {
    start: Vec<u32>,
    list: Vec<u32>,
}

impl Neighbours {
    /// The table, unless it would hold more than [`Self::MAX_ROW`] entries per contact on
    /// average: a body with `D` contacts puts `D` entries in each of their rows, `D²` in all (a
    /// large moving body under thousands of grains).
    fn new(m: &MatrixFree) -> Option<Self> {
        let incidence = m.incidence();
        let nc = m.rows.len();
        let entries: usize = (0..m.bodies.len())
            .filter(|&k| m.bodies[k] != Body::fixed())
            .map(|k| (incidence.start[k + 1] - incidence.start[k]).pow(2))
            .sum();
        if entries > Self::MAX_ROW * nc || entries >= u32::MAX as usize {
            return None;
        }
        // Rows built by chunks of contacts on threads, then joined in order.
        let chunk_rows = |chunk: usize| {
            let (mut ends, mut list) = (Vec::with_capacity(CHUNK), Vec::with_capacity(16 * CHUNK));
            for a in chunk * CHUNK..nc.min((chunk + 1) * CHUNK) {
                let row = list.len();
                let mut own = row;
                for k in m.moving_bodies_of(a) {
                    for b in incidence.contacts_of(k) {
                        // A body lists a contact once: only body j's may repeat body i's.
                        if !list[row..own].contains(&(b as u32)) {
                            list.push(b as u32);
                        }
                    }
                    own = list.len();
                }
                ends.push(list.len() as u32);
            }
            (ends, list)
        };
        let chunks: Vec<(Vec<u32>, Vec<u32>)> = match parallel(nc) {
            true => (0..nc.div_ceil(CHUNK)).into_par_iter().map(chunk_rows).collect(),
            false => (0..nc.div_ceil(CHUNK)).map(chunk_rows).collect(),
        };
        let (mut start, mut list) = (Vec::with_capacity(nc + 1), Vec::with_capacity(entries));
        start.push(0u32);
        for (ends, rows) in chunks {
            let offset = list.len() as u32;
            start.extend(ends.iter().map(|end| offset + end));
            list.extend_from_slice(&rows);
        }
        Some(Self { start, list })
    }

    /// Entries per contact, on average, above which no table is kept.
    pub const MAX_ROW: usize = 32;
}

/// Each contact's neighbours, from the [`Neighbours`] table where the operator keeps one, else
/// from its bodies' contact lists (the same contacts in the same order, repeated where both
/// bodies touch one).
#[derive(Clone, Copy)]
pub struct ContactNeighbours<'a> {
    op: &'a MatrixFree,
    table: Option<&'a Neighbours>,
}

impl<'a> ContactNeighbours<'a> {
    /// Contact `a`'s neighbours, itself included (none when neither of its bodies moves).
    #[inline]
    pub fn of(&self, a: usize) -> impl Iterator<Item = usize> + 'a {
        let op = self.op;
        match self.table {
            Some(t) => Either::Left(t.list[t.start[a] as usize..t.start[a + 1] as usize].iter().map(|&c| c as usize)),
            None => Either::Right(op.moving_bodies_of(a).flat_map(move |k| op.incidence().contacts_of(k))),
        }
    }

    /// `f` on each of contact `a`'s neighbours, in [`Self::of`]'s order: the table's row as a
    /// plain loop (stepping `of`'s iterator took 7–8 % of a 40,000-disk pile's step).
    #[inline]
    pub fn for_each(&self, a: usize, mut f: impl FnMut(usize)) {
        match self.table {
            Some(t) => t.list[t.start[a] as usize..t.start[a + 1] as usize].iter().for_each(|&c| f(c as usize)),
            None => self.of(a).for_each(f),
        }
    }

    /// Whether a table serves them.
    pub fn tabled(&self) -> bool {
        self.table.is_some()
    }
}

fn cross(a: [f64; 2], b: [f64; 2]) -> f64 {
    a[0] * b[1] - a[1] * b[0]
}

impl MatrixFree {
    /// Builds the operator with every dof (rotation and friction), checking indices, masses and normals.
    pub fn new(bodies: Vec<Body>, contacts: &[Contact]) -> Result<Self, String> {
        Self::with_dofs(bodies, contacts, Dofs::ALL)
    }

    /// Builds the operator for the dofs a scene uses; lever arms are ignored without rotation.
    pub fn with_dofs(bodies: Vec<Body>, contacts: &[Contact], dofs: Dofs) -> Result<Self, String> {
        Self::from_contacts(bodies, contacts.len(), |a| contacts[a], dofs)
    }

    /// [`Self::with_dofs`] of the `n` contacts `contact(a)`, made as they are read rather than
    /// kept (the stepping makes them from the detected contacts): checked and turned into rows
    /// in one pass on threads, a pass over a few megabytes costing about a millisecond.
    pub fn from_contacts(
        bodies: Vec<Body>,
        n: usize,
        contact: impl Fn(usize) -> Contact + Sync + Send,
        dofs: Dofs,
    ) -> Result<Self, String> {
        for (k, b) in bodies.iter().enumerate() {
            if !(b.inv_mass.is_finite() && b.inv_mass >= 0.0) {
                return Err(format!("body {k}: inverse mass {} must be finite and >= 0 (mass > 0)", b.inv_mass));
            }
            if !(b.inv_inertia.is_finite() && b.inv_inertia >= 0.0) {
                return Err(format!("body {k}: inverse inertia {} must be finite and >= 0", b.inv_inertia));
            }
        }
        let nb = bodies.len();
        let normal_length = |c: &Contact| (c.normal[0] * c.normal[0] + c.normal[1] * c.normal[1]).sqrt();
        // Contact `a`, whose normal is `len` long.
        let check = |a: usize, c: &Contact, len: f64| {
            if c.i >= nb || c.j.is_some_and(|j| j >= nb || j == c.i) {
                return Err(format!("contact {a}: bodies ({}, {:?}) out of range or equal ({nb} bodies)", c.i, c.j));
            }
            if !len.is_finite() || (len - 1.0).abs() > 1e-6 {
                return Err(format!("contact {a}: normal {:?} is not a unit vector", c.normal));
            }
            if dofs.rotation && !c.lever_i.iter().chain(&c.lever_j).all(|x| x.is_finite()) {
                return Err(format!("contact {a}: lever arm is not finite"));
            }
            Ok(())
        };
        // Built unchecked with a flag raised on a bad contact; the first bad one is then named.
        let bad = AtomicBool::new(false);
        let row = |a: usize| {
            let c = contact(a);
            let len = normal_length(&c);
            if check(a, &c, len).is_err() {
                bad.store(true, Relaxed);
            }
            (ContactRows { i: c.i, j: c.j.unwrap_or(NO_BODY), n: [c.normal[0] / len, c.normal[1] / len] }, c)
        };
        let with_levers = |a: usize| {
            let (rows, c) = row(a);
            let (n, t) = (rows.n, [-rows.n[1], rows.n[0]]);
            (rows, [cross(c.lever_i, n), cross(c.lever_i, t), cross(c.lever_j, n), cross(c.lever_j, t)])
        };
        let (rows, levers): (Vec<ContactRows>, Vec<Levers>) = match (dofs.rotation, parallel(n)) {
            (true, true) => (0..n).into_par_iter().with_min_len(CHUNK).map(with_levers).unzip(),
            (true, false) => (0..n).map(with_levers).unzip(),
            (false, _) => (map_indices(n, |a| row(a).0), Vec::new()),
        };
        if bad.load(Relaxed) {
            first_failure(n, |a| {
                let c = contact(a);
                check(a, &c, normal_length(&c))
            })?;
        }
        Ok(Self {
            bodies,
            rows,
            levers,
            dofs,
            incidence: OnceLock::new(),
            neighbours: OnceLock::new(),
            block_colours: OnceLock::new(),
            colouring: OnceLock::new(),
            diag: OnceLock::new(),
            rolling_radius: Vec::new(),
            held: Vec::new(),
        })
    }

    /// The operator with body `k` holding its velocity along x (`held[k][0]`) and y: its inverse
    /// mass along them is zero (the plate of a shear cell, driven along x, pressed along y).
    pub fn with_held_axes(mut self, held: Vec<[bool; 2]>) -> Result<Self, String> {
        if held.len() != self.bodies.len() {
            return Err(format!("{} held axes for {} bodies", held.len(), self.bodies.len()));
        }
        self.held = if held.iter().any(|h| h[0] || h[1]) { held } else { Vec::new() };
        self.diag = OnceLock::new();
        Ok(self)
    }

    /// The axes (x, y) along which body `k` holds its velocity.
    pub fn held_axes(&self, k: usize) -> [bool; 2] {
        self.held.get(k).copied().unwrap_or([false; 2])
    }

    /// Body `k`'s inverse mass along x and y: 0 along an axis it holds.
    #[inline(always)]
    fn axis_inv_mass(&self, k: usize, b: Body) -> [f64; 2] {
        match self.held.get(k) {
            None => [b.inv_mass; 2],
            Some(h) => h.map(|held| if held { 0.0 } else { b.inv_mass }),
        }
    }

    /// The operator with a rolling row per contact (`radius[a]` its rolling radius): unknowns
    /// become `[r_n0, r_t0, …, r_n(m−1), r_t(m−1), r_r0, …, r_r(m−1)]`. Needs rotation.
    pub fn with_rolling(mut self, radius: Vec<f64>) -> Result<Self, String> {
        if !self.dofs.rotation {
            return Err("rolling resistance needs the effect `rotation`".into());
        }
        if radius.len() != self.rows.len() {
            return Err(format!("{} rolling radii for {} contacts", radius.len(), self.rows.len()));
        }
        if let Some(a) = radius.iter().position(|r| !(r.is_finite() && *r > 0.0)) {
            return Err(format!("contact {a}: rolling radius {} must be finite and > 0", radius[a]));
        }
        self.rolling_radius = radius;
        Ok(self)
    }

    /// The same operator without rolling rows.
    pub fn without_rolling(&self) -> Self {
        Self { rolling_radius: Vec::new(), ..self.clone() }
    }

    /// Whether each contact has a rolling row.
    pub fn has_rolling(&self) -> bool {
        !self.rolling_radius.is_empty()
    }

    /// Unknowns of a problem on this operator: 2 per contact, 3 with rolling rows.
    pub fn unknowns(&self) -> usize {
        if self.has_rolling() {
            3 * self.rows.len()
        } else {
            2 * self.rows.len()
        }
    }

    /// `v += M⁻¹ B_rᵀ r_r`: contact `a`'s rolling impulse turned into spins (fixed bodies untouched).
    #[inline]
    pub(crate) fn scatter_rolling<V: Velocities + ?Sized>(&self, a: usize, rr: f64, v: &mut V) {
        let c = &self.rows[a];
        let torque = self.rolling_radius[a] * rr;
        let b = self.bodies[c.i];
        if b != Body::fixed() {
            v.add(3 * c.i + 2, b.inv_inertia * torque);
        }
        if c.j != NO_BODY && self.bodies[c.j] != Body::fixed() {
            v.add(3 * c.j + 2, -(self.bodies[c.j].inv_inertia * torque));
        }
    }

    /// `B_r v`: contact `a`'s rolling velocity `R (ω_i − ω_j)`.
    #[inline]
    pub(crate) fn gather_rolling<V: Velocities + ?Sized>(&self, a: usize, v: &V) -> f64 {
        let c = &self.rows[a];
        let spin_j = if c.j != NO_BODY { v.get(3 * c.j + 2) } else { 0.0 };
        self.rolling_radius[a] * (v.get(3 * c.i + 2) - spin_j)
    }

    /// Contact `a`'s rolling radius (with rolling rows).
    pub fn rolling_radius(&self, a: usize) -> f64 {
        self.rolling_radius[a]
    }

    /// `W_rr` of contact `a`: `R² (1/I_i + 1/I_j)`.
    pub fn rolling_diag(&self, a: usize) -> f64 {
        let c = &self.rows[a];
        let inv_j = if c.j != NO_BODY { self.bodies[c.j].inv_inertia } else { 0.0 };
        self.rolling_radius[a].powi(2) * (self.bodies[c.i].inv_inertia + inv_j)
    }

    /// Number of contacts.
    pub fn n_contacts(&self) -> usize {
        self.rows.len()
    }

    /// Number of bodies.
    pub fn n_bodies(&self) -> usize {
        self.bodies.len()
    }

    /// Which dofs the operator carries.
    pub fn dofs(&self) -> Dofs {
        self.dofs
    }

    /// Bytes held by the operator (bodies, contact rows, lever arms).
    pub fn memory_bytes(&self) -> usize {
        self.bodies.capacity() * std::mem::size_of::<Body>()
            + self.rows.capacity() * std::mem::size_of::<ContactRows>()
            + self.levers.capacity() * std::mem::size_of::<Levers>()
            + self.rolling_radius.capacity() * std::mem::size_of::<f64>()
            + self.held.capacity() * std::mem::size_of::<[bool; 2]>()
    }

    /// The same operator with its contacts in `order` (contact `k` of the result is `order[k]`).
    pub fn permuted(&self, order: &[usize]) -> Self {
        Self {
            bodies: self.bodies.clone(),
            rows: order.iter().map(|&a| self.rows[a]).collect(),
            levers: if self.dofs.rotation { order.iter().map(|&a| self.levers[a]).collect() } else { Vec::new() },
            dofs: self.dofs,
            incidence: OnceLock::new(),
            neighbours: OnceLock::new(),
            block_colours: OnceLock::new(),
            colouring: OnceLock::new(),
            diag: OnceLock::new(),
            rolling_radius: order.iter().filter_map(|&a| self.rolling_radius.get(a).copied()).collect(),
            held: self.held.clone(),
        }
    }

    /// The colouring of the contact graph (contacts sharing a moving body conflict): the one
    /// handed in by [`Self::give_colouring`], else the greedy one, built once.
    pub fn colouring(&self) -> &Colouring {
        self.colouring.get_or_init(|| Colouring::matrix_free_greedy(self))
    }

    /// Body `k`'s inverse mass per velocity (x, y, spin): 0 where the impulses cannot move it (a
    /// fixed body, a held axis, a body that does not turn).
    fn dof_inv_mass(&self, k: usize) -> [f64; 3] {
        let b = self.bodies[k];
        let [mx, my] = self.axis_inv_mass(k, b);
        [mx, my, b.inv_inertia]
    }

    /// The impulses' power `(Bᵀ r)·v` into the velocities they move, from `dv = M⁻¹ Bᵀ r`:
    /// `Σ (M dv)·v` over those velocities, `v(i)` the velocity of index `i` as they are stored;
    /// and `v` where the impulses cannot move the bodies (fixed bodies, held axes, bodies that do
    /// not turn), zero elsewhere, `None` when that part is zero throughout (nothing is driven).
    pub fn impulse_power(&self, dv: &[f64], v: impl Fn(usize) -> f64 + Sync + Send) -> (f64, Option<Vec<f64>>) {
        let s = self.dofs.per_body();
        let [power, driven] = crate::parallel::chunked_sums(self.bodies.len(), |k| {
            let inv = self.dof_inv_mass(k);
            (0..s).fold([0.0, 0.0], |[power, driven], d| match inv[d] > 0.0 {
                true => [power + dv[s * k + d] / inv[d] * v(s * k + d), driven],
                false => [power, driven + f64::from(u8::from(v(s * k + d) != 0.0))],
            })
        });
        let unmoved = |i: usize| if self.dof_inv_mass(i / s)[i % s] == 0.0 { v(i) } else { 0.0 };
        (power, (driven > 0.0).then(|| map_indices(s * self.bodies.len(), unmoved)))
    }

    /// Which bodies can move (a contact between two of them conflicts in a Gauss–Seidel sweep).
    pub fn moving(&self) -> Vec<bool> {
        self.bodies.iter().map(|b| *b != Body::fixed()).collect()
    }

    /// The colouring if one was built or handed in (a solve used it).
    pub fn colouring_if_built(&self) -> Option<&Colouring> {
        self.colouring.get()
    }

    /// Hands in a proper colouring of this operator's contact graph (checked in debug builds);
    /// ignored if one was built already.
    pub fn give_colouring(&self, colouring: Colouring) {
        debug_assert!(colouring.is_proper(Colouring::neighbours_in_matrix_free(self)));
        let _ = self.colouring.set(colouring);
    }

    /// The neighbour table if one was built or handed in (a work list used it), for the next
    /// step's operator.
    pub fn neighbours_if_built(&self) -> Option<Arc<Neighbours>> {
        self.neighbours.get().cloned().flatten()
    }

    /// Hands in the neighbour table of an operator whose contacts join the same bodies in the
    /// same order, with the same bodies moving (checked in debug builds); ignored if one was
    /// built already. Why: at 81,000 contacts the table costs 3–6 ms a step to build, and a
    /// settled pile keeps its contact graph from step to step.
    pub fn give_neighbours(&self, table: Arc<Neighbours>) {
        debug_assert!(Neighbours::new(self).as_ref() == Some(&*table));
        let _ = self.neighbours.set(Some(table));
    }

    /// The threaded sweeps' blocks by colour (`None`: the contacts are not banded enough), built
    /// once by `build` unless handed in.
    pub fn block_colours_with(&self, build: impl FnOnce(&Self) -> Option<BlockColours>) -> Option<Arc<BlockColours>> {
        self.block_colours.get_or_init(|| build(self).map(Arc::new)).clone()
    }

    /// The blocks by colour, if built (to hand to the next step with the neighbour table).
    pub fn block_colours_if_built(&self) -> Option<Arc<BlockColours>> {
        self.block_colours.get().cloned().flatten()
    }

    /// Hands in the blocks by colour of an operator with the same contacts and moving bodies (as
    /// [`Self::give_neighbours`]); ignored if built already. Why: 0.4 ms a step at 81,000
    /// contacts, one pass that does not thread.
    pub fn give_block_colours(&self, blocks: Arc<BlockColours>) {
        let _ = self.block_colours.set(Some(blocks));
    }

    /// Each body's contacts (built once).
    pub fn incidence(&self) -> &Incidence {
        self.incidence.get_or_init(|| Arc::new(Incidence::new(self.bodies.len(), &self.rows)))
    }

    /// Each body's contacts if built, for the next step's operator (as the neighbour table).
    pub fn incidence_if_built(&self) -> Option<Arc<Incidence>> {
        self.incidence.get().cloned()
    }

    /// Hands in the contacts of each body of an operator whose contacts join the same bodies in
    /// the same order (checked in debug builds); ignored if built already. Why: a serial pass of
    /// 1-2 ms a step at 81,000 contacts, before a threaded solve can start.
    pub fn give_incidence(&self, incidence: Arc<Incidence>) {
        debug_assert!(Incidence::new(self.bodies.len(), &self.rows) == *incidence);
        let _ = self.incidence.set(incidence);
    }

    /// Contact `a`'s rows of `B` and its lever arms (`None` without rotation), for
    /// [`Self::gather_rows`].
    pub(crate) fn rows_of(&self, a: usize) -> (ContactRows, Option<Levers>) {
        (self.rows[a], self.levers.get(a).copied())
    }

    /// Each contact's neighbours read from its bodies' contact lists, with no table built.
    pub fn neighbours_from_bodies(&self) -> ContactNeighbours<'_> {
        ContactNeighbours { op: self, table: None }
    }

    /// Each contact's neighbours (their table built once, where it stays small).
    pub fn neighbours(&self) -> ContactNeighbours<'_> {
        let table = self.neighbours.get_or_init(|| Neighbours::new(self).map(Arc::new)).as_deref();
        ContactNeighbours { op: self, table }
    }

    /// The bodies of contact `a` that can move (a contact between them and another one conflicts
    /// in a Gauss–Seidel sweep).
    pub fn moving_bodies_of(&self, a: usize) -> impl Iterator<Item = usize> + '_ {
        let c = &self.rows[a];
        [c.i, c.j].into_iter().filter(|&k| k != NO_BODY && self.bodies[k] != Body::fixed())
    }

    /// Body `k`'s velocity `(M⁻¹ Bᵀ r)_k`, summed over its contacts in contact order.
    fn body_velocity_into(&self, k: usize, r: &[f64], v: &mut [f64]) {
        v.fill(0.0);
        let b = self.bodies[k];
        if b == Body::fixed() {
            return;
        }
        let [mx, my] = self.axis_inv_mass(k, b);
        let inc = self.incidence();
        let nc = self.rows.len();
        for &(a, j_side) in &inc.list[inc.start[k]..inc.start[k + 1]] {
            let (rn, rt) = (r[2 * a], r[2 * a + 1]);
            let n = self.rows[a].n;
            let p = if self.dofs.friction {
                [rn * n[0] - rt * n[1], rn * n[1] + rt * n[0]]
            } else {
                [rn * n[0], rn * n[1]]
            };
            let sign = if j_side { -1.0 } else { 1.0 };
            v[0] += sign * (mx * p[0]);
            v[1] += sign * (my * p[1]);
            if self.dofs.rotation {
                let g = &self.levers[a];
                let torque = match (j_side, self.dofs.friction) {
                    (false, true) => rn * g[0] + rt * g[1],
                    (false, false) => rn * g[0],
                    (true, true) => rn * g[2] + rt * g[3],
                    (true, false) => rn * g[2],
                };
                v[2] += sign * (b.inv_inertia * torque);
                if self.has_rolling() {
                    // The order of `scatter_rolling` after `scatter_one`: the same bits.
                    v[2] += sign * (b.inv_inertia * (self.rolling_radius[a] * r[2 * nc + a]));
                }
            }
        }
    }

    /// `v += M⁻¹ B_aᵀ r_a` for one contact (velocities stored with [`Dofs::per_body`] entries per
    /// body). Fixed bodies are never written: their velocity stays zero, and a threaded sweep
    /// whose colouring ignores them never writes one place from two threads.
    #[inline]
    pub(crate) fn scatter_one<V: Velocities + ?Sized>(&self, a: usize, rn: f64, rt: f64, v: &mut V) {
        self.scatter_rows(&self.rows[a], self.levers.get(a), rn, rt, v)
    }

    /// [`Self::scatter_one`] from a copy of the contact's rows and lever arms (`None` without
    /// rotation), as [`Self::gather_rows`].
    #[inline]
    pub(crate) fn scatter_rows<V: Velocities + ?Sized>(
        &self,
        c: &ContactRows,
        levers: Option<&Levers>,
        rn: f64,
        rt: f64,
        v: &mut V,
    ) {
        let n = c.n;
        let p =
            if self.dofs.friction { [rn * n[0] - rt * n[1], rn * n[1] + rt * n[0]] } else { [rn * n[0], rn * n[1]] };
        let s = self.dofs.per_body();
        let g = match levers {
            Some(g) if self.dofs.rotation => *g,
            _ => [0.0; 4],
        };
        let b = self.bodies[c.i];
        if b != Body::fixed() {
            let [mx, my] = self.axis_inv_mass(c.i, b);
            v.add(s * c.i, mx * p[0]);
            v.add(s * c.i + 1, my * p[1]);
            if self.dofs.rotation {
                let torque_i = if self.dofs.friction { rn * g[0] + rt * g[1] } else { rn * g[0] };
                v.add(s * c.i + 2, b.inv_inertia * torque_i);
            }
        }
        if c.j != NO_BODY && self.bodies[c.j] != Body::fixed() {
            let b = self.bodies[c.j];
            if self.dofs.rotation {
                let torque_j = if self.dofs.friction { rn * g[2] + rt * g[3] } else { rn * g[2] };
                v.add(s * c.j + 2, -(b.inv_inertia * torque_j));
            }
            let [mx, my] = self.axis_inv_mass(c.j, b);
            v.add(s * c.j, -(mx * p[0]));
            v.add(s * c.j + 1, -(my * p[1]));
        }
    }

    /// `B_a v`: the relative velocity (u_n, u_t) of contact `a` (u_t = 0 without friction).
    #[inline]
    pub(crate) fn gather_one<V: Velocities + ?Sized>(&self, a: usize, v: &V) -> [f64; 2] {
        self.gather_rows(&self.rows[a], self.levers.get(a), v)
    }

    /// [`Self::gather_one`] from a copy of the contact's rows and lever arms (`None` without
    /// rotation), kept beside other per-contact data by a caller that reads them often.
    #[inline]
    pub(crate) fn gather_rows<V: Velocities + ?Sized>(&self, c: &ContactRows, g: Option<&Levers>, v: &V) -> [f64; 2] {
        let n = c.n;
        let s = self.dofs.per_body();
        let mut dv = [v.get(s * c.i), v.get(s * c.i + 1)];
        if c.j != NO_BODY {
            dv[0] -= v.get(s * c.j);
            dv[1] -= v.get(s * c.j + 1);
        }
        let mut un = n[0] * dv[0] + n[1] * dv[1];
        let mut ut = if self.dofs.friction { -n[1] * dv[0] + n[0] * dv[1] } else { 0.0 };
        if let Some(g) = g {
            let wi = v.get(s * c.i + 2);
            un += g[0] * wi;
            if self.dofs.friction {
                ut += g[1] * wi;
            }
            if c.j != NO_BODY {
                let wj = v.get(s * c.j + 2);
                un -= g[2] * wj;
                if self.dofs.friction {
                    ut -= g[3] * wj;
                }
            }
        }
        [un, ut]
    }

    /// Body velocities `M⁻¹ Bᵀ r` ([`Dofs::per_body`] entries per body): on threads, each body
    /// sums its own contacts (no two threads write one body); the same bits either way.
    pub fn body_velocities(&self, r: &[f64]) -> Vec<f64> {
        let s = self.dofs.per_body();
        let mut v = filled(s * self.bodies.len(), 0.0);
        if parallel(self.rows.len()) {
            v.par_chunks_mut(s * CHUNK).enumerate().for_each(|(chunk, vs)| {
                for (k, vk) in vs.chunks_mut(s).enumerate() {
                    self.body_velocity_into(chunk * CHUNK + k, r, vk);
                }
            });
        } else {
            let nc = self.rows.len();
            for a in 0..nc {
                self.scatter_one(a, r[2 * a], r[2 * a + 1], v.as_mut_slice());
                if self.has_rolling() {
                    self.scatter_rolling(a, r[2 * nc + a], v.as_mut_slice());
                }
            }
        }
        v
    }

    /// `out = B v` (contacts on threads for large problems); rolling rows after the (n, t) rows.
    pub fn contact_velocities(&self, v: &[f64], out: &mut [f64]) {
        self.contact_velocities_plus(v, None, out);
    }

    /// `out = B v + q` ([`Self::contact_velocities`] with `q` added as each entry is made, not in
    /// a pass of its own after).
    pub fn contact_velocities_plus(&self, v: &[f64], q: Option<&[f64]>, out: &mut [f64]) {
        let nc = self.rows.len();
        // Nothing added without `q` (not even 0, which would turn −0 into +0).
        let plus = |x: f64, k: usize| q.map_or(x, |q| x + q[k]);
        let (out, rolling) = out.split_at_mut(2 * nc);
        for (a, u) in rolling.iter_mut().enumerate() {
            *u = plus(self.gather_rolling(a, v), 2 * nc + a);
        }
        let gather = |first: usize, out: &mut [f64]| self.gather_pairs(first, v, plus, out);
        if parallel(self.rows.len()) {
            out.par_chunks_mut(2 * CHUNK).enumerate().for_each(|(c, o)| gather(c * CHUNK, o));
        } else {
            gather(0, out);
        }
    }

    /// `out = B v + q` as [`Self::contact_velocities_plus`] makes it (no rolling rows), and the
    /// [`fill_and_sum`] of `term(a, u_a)` over the contacts, each taken as its chunk is made.
    pub fn contact_velocities_summing<const M: usize>(
        &self,
        v: &[f64],
        q: &[f64],
        out: &mut [f64],
        term: impl Fn(usize, [f64; 2]) -> [f64; M] + Sync,
    ) -> [f64; M] {
        assert!(!self.has_rolling(), "the pairs' gather only");
        let gather = |first: usize, part: &mut [f64]| self.gather_pairs(first, v, |x, k| x + q[k], part);
        fill_and_sum(self.rows.len(), (out, 2), gather, |a, u| term(a, [u[0], u[1]]))
    }

    /// The (n, t) velocities of contacts `first..` into `out`, a pair each, entry `k` of `B v`
    /// passed through `plus(x, k)` (where a caller adds `q`). Always inlined: as a call of its own
    /// (`#[inline]` was not enough) the plain product took 0.30 ms on 20,321 contacts, 0.23 inlined.
    #[inline(always)]
    fn gather_pairs(&self, first: usize, v: &[f64], plus: impl Fn(f64, usize) -> f64, out: &mut [f64]) {
        // Entry by entry, not through `copy_from_slice`: on a slice of unknown length that was a
        // call to `memmove` for each contact (a product on 81,000 contacts took 1.3 ms, 0.95
        // without it, one thread).
        for (k, o) in out.chunks_exact_mut(2).enumerate() {
            let a = first + k;
            let u = self.gather_one(a, v);
            o[0] = plus(u[0], 2 * a);
            o[1] = plus(u[1], 2 * a + 1);
        }
    }

    /// `out = W r`: a scatter to the bodies and a gather back.
    pub fn apply(&self, r: &[f64], out: &mut [f64]) {
        let v = self.body_velocities(r);
        self.contact_velocities(&v, out);
    }

    /// Lever terms `(ρ_i×n, ρ_i×t)` and `(ρ_j×n, ρ_j×t)` of contact `a` (zero without rotation).
    fn lever_pair(&self, a: usize) -> ([f64; 2], [f64; 2]) {
        if self.dofs.rotation {
            let g = self.levers[a];
            ([g[0], g[1]], [g[2], g[3]])
        } else {
            ([0.0; 2], [0.0; 2])
        }
    }

    /// Diagonal block `W_aa`. Without friction the tangential row is decoupled (`r_t ≡ 0`); its
    /// diagonal is set to `W_nn` so that block inverses used by preconditioners stay defined.
    /// Every diagonal block, built once (on threads for a large problem: the same values).
    pub fn diag_blocks(&self) -> &[Mat2] {
        self.diag.get_or_init(|| map_indices(self.n_contacts(), |a| self.diag_block(a)))
    }

    /// The first contact whose diagonal block is `bad`, the blocks made in the same pass when
    /// they are not made yet ([`Self::diag_blocks`]'s values): a check that read them after they
    /// were made read 2.6 MB again on the 40,000-disk pile, from memory.
    pub fn first_bad_diag_block(&self, bad: impl Fn(&Mat2) -> bool + Sync + Send) -> Option<usize> {
        if let Some(blocks) = self.diag.get() {
            return first_failure(blocks.len(), |a| if bad(&blocks[a]) { Err(a) } else { Ok(()) }).err();
        }
        let n = self.n_contacts();
        let mut blocks = filled(n, [0.0; 4]);
        let fill = |(c, part): (usize, &mut [Mat2])| {
            part.iter_mut().enumerate().for_each(|(k, w)| *w = self.diag_block(c * CHUNK + k));
            part.iter().position(&bad).map(|k| c * CHUNK + k)
        };
        // Every chunk made, past a bad block too: the blocks are kept.
        let first = match parallel(n) {
            true => blocks.par_chunks_mut(CHUNK).enumerate().map(fill).reduce(|| None, Option::or),
            false => blocks.chunks_mut(CHUNK).enumerate().map(fill).fold(None, Option::or),
        };
        // Another thread may have made them meanwhile: the same values.
        let _ = self.diag.set(blocks);
        first
    }

    /// The diagonal block `W_aa` of contact `a`.
    pub fn diag_block(&self, a: usize) -> Mat2 {
        let c = &self.rows[a];
        let (gi, gj) = self.lever_pair(a);
        let mut w = [0.0; 4];
        // n·M⁻¹n and the like: `1/m` itself (n and t are unit vectors) unless the body holds
        // its velocity along an axis.
        let [nx, ny] = c.n;
        let mut add = |k: usize, g: [f64; 2]| {
            let b = self.bodies[k];
            let [mx, my] = self.axis_inv_mass(k, b);
            let (nn, nt, tt) = match mx == my {
                true => (mx, 0.0, mx),
                false => (mx * nx * nx + my * ny * ny, (my - mx) * nx * ny, mx * ny * ny + my * nx * nx),
            };
            w[0] += nn + b.inv_inertia * g[0] * g[0];
            w[1] += nt + b.inv_inertia * g[0] * g[1];
            w[3] += tt + b.inv_inertia * g[1] * g[1];
        };
        add(c.i, gi);
        if c.j != NO_BODY {
            add(c.j, gj);
        }
        if !self.dofs.friction {
            w[1] = 0.0;
            w[3] = w[0];
        }
        w[2] = w[1];
        w
    }

    /// Assembles `W` explicitly (for writing problem files; O(Σ deg²) blocks).
    pub fn assemble(&self) -> BlockSparse {
        let nb = self.bodies.len();
        let mut incident: Vec<Vec<(usize, f64, [f64; 2])>> = vec![Vec::new(); nb];
        for (a, c) in self.rows.iter().enumerate() {
            let (gi, gj) = self.lever_pair(a);
            incident[c.i].push((a, 1.0, gi));
            if c.j != NO_BODY {
                incident[c.j].push((a, -1.0, gj));
            }
        }
        let mut triplets: Vec<(usize, usize, Mat2)> = Vec::new();
        for (k, list) in incident.iter().enumerate() {
            let b = self.bodies[k];
            if b == Body::fixed() {
                continue;
            }
            // x·M⁻¹y over the translations (`1/m x·y` unless held along an axis).
            let [mx, my] = self.axis_inv_mass(k, b);
            let dot = |x: [f64; 2], y: [f64; 2]| match mx == my {
                true => mx * (x[0] * y[0] + x[1] * y[1]),
                false => mx * x[0] * y[0] + my * x[1] * y[1],
            };
            for &(a, sa, ga) in list {
                for &(c, sc, gc) in list {
                    let (na, nc) = (self.rows[a].n, self.rows[c].n);
                    let (ta, tc) = ([-na[1], na[0]], [-nc[1], nc[0]]);
                    let s = sa * sc;
                    let blk = [
                        s * (dot(na, nc) + b.inv_inertia * ga[0] * gc[0]),
                        s * (dot(na, tc) + b.inv_inertia * ga[0] * gc[1]),
                        s * (dot(ta, nc) + b.inv_inertia * ga[1] * gc[0]),
                        s * (dot(ta, tc) + b.inv_inertia * ga[1] * gc[1]),
                    ];
                    let blk = if self.dofs.friction { blk } else { [blk[0], 0.0, 0.0, 0.0] };
                    triplets.push((a, c, blk));
                }
            }
        }
        if !self.dofs.friction {
            // The decoupled tangential diagonal, as in `diag_block`.
            triplets.extend((0..self.rows.len()).map(|a| (a, a, [0.0, 0.0, 0.0, self.diag_block(a)[3]])));
        }
        BlockSparse::from_block_triplets(self.rows.len(), triplets)
    }
}

/// Eight unit disks (mass 1, inertia 0.5) in a row on a floor, for tests: contact i joins disks
/// i and i + 1 (0–6), contact 7 + i puts disk i on the floor.
#[cfg(test)]
pub(crate) fn disks_in_a_row() -> MatrixFree {
    let bodies = vec![Body::dynamic(1.0, 0.5); 8];
    let between =
        |i: usize| Contact { i: i + 1, j: Some(i), normal: [1.0, 0.0], lever_i: [-1.0, 0.0], lever_j: [1.0, 0.0] };
    let floor = |i: usize| Contact { i, j: None, normal: [0.0, 1.0], lever_i: [0.0, -1.0], lever_j: [0.0, 0.0] };
    let contacts: Vec<Contact> = (0..7).map(between).chain((0..8).map(floor)).collect();
    MatrixFree::new(bodies, &contacts).expect("a valid row")
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `B v + q` made in the gather is `B v` with `q` added after, to the bit, on one thread and
    /// on four (a problem long enough for the threaded gather); `B v` alone is each contact's
    /// gather as it is.
    #[test]
    fn contact_velocities_plus_q_are_the_product_with_q_added_after() {
        let n = 3 * crate::parallel::PARALLEL_MIN + 5;
        let bodies = vec![Body::dynamic(1.5, 0.4); n + 1];
        let contact = |a: usize| {
            let angle = 0.37 * a as f64;
            let normal = [angle.cos(), angle.sin()];
            Contact {
                i: a + 1,
                j: (!a.is_multiple_of(3)).then_some(a),
                normal,
                lever_i: [0.2, -0.1],
                lever_j: [-0.3, 0.05],
            }
        };
        let op = MatrixFree::from_contacts(bodies, n, contact, Dofs::ALL).expect("valid contacts");
        let v: Vec<f64> = (0..3 * (n + 1)).map(|k| ((k as f64) * 0.613).sin()).collect();
        let q: Vec<f64> = (0..2 * n).map(|k| ((k as f64) * 1.7).cos() - 0.2).collect();
        for threads in [1, 4] {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            let (mut plain, mut plus) = (vec![0.0; 2 * n], vec![0.0; 2 * n]);
            pool.install(|| {
                op.contact_velocities(&v, &mut plain);
                op.contact_velocities_plus(&v, Some(&q), &mut plus);
            });
            let after: Vec<u64> = plain.iter().zip(&q).map(|(u, q)| (u + q).to_bits()).collect();
            assert_eq!(plus.iter().map(|u| u.to_bits()).collect::<Vec<_>>(), after, "{threads} thread(s)");
        }
        // Without `q`, each contact's own gather, nothing added.
        let mut plain = vec![0.0; 2 * n];
        op.contact_velocities(&v, &mut plain);
        let own: Vec<u64> = (0..n).flat_map(|a| op.gather_one(a, v.as_slice())).map(f64::to_bits).collect();
        assert_eq!(plain.iter().map(|u| u.to_bits()).collect::<Vec<_>>(), own);
    }

    /// Bodies held along x or y (a zero inverse mass along that axis) enter `W = B M⁻¹ Bᵀ` as
    /// such: the product, the diagonal blocks and the assembled matrix agree with `B M⁻¹ Bᵀ`
    /// formed densely, for contacts at every angle.
    #[test]
    fn bodies_held_along_one_axis_give_w_as_b_m_inverse_b_transpose() {
        let bodies = vec![Body::dynamic(2.0, 0.3), Body::dynamic(2.0, 0.25), Body::dynamic(4.0, 0.0)];
        let contacts: Vec<Contact> = (0..7)
            .map(|a| {
                let angle = 0.3 + a as f64 * 0.9;
                let normal = [angle.cos(), angle.sin()];
                let (i, j) =
                    [(1, Some(0)), (2, Some(1)), (1, None), (2, None), (0, Some(2)), (1, Some(2)), (0, None)][a];
                Contact { i, j, normal, lever_i: [0.1 * a as f64, -0.2], lever_j: [-0.3, 0.05 * a as f64] }
            })
            .collect();
        let held = vec![[false, false], [true, false], [false, true]];
        let op = MatrixFree::new(bodies.clone(), &contacts).unwrap().with_held_axes(held.clone()).unwrap();
        let (nc, nb) = (contacts.len(), bodies.len());
        // B: 2 rows a contact (n, t), 3 columns a body (x, y, θ).
        let mut b = vec![vec![0.0; 3 * nb]; 2 * nc];
        for (a, c) in contacts.iter().enumerate() {
            let [nx, ny] = c.normal;
            let (n, t) = ([nx, ny], [-ny, nx]);
            for (k, lever, sign) in [(Some(c.i), c.lever_i, 1.0), (c.j, c.lever_j, -1.0)] {
                let Some(k) = k else { continue };
                for (row, dir) in [(2 * a, n), (2 * a + 1, t)] {
                    b[row][3 * k] += sign * dir[0];
                    b[row][3 * k + 1] += sign * dir[1];
                    b[row][3 * k + 2] += sign * (lever[0] * dir[1] - lever[1] * dir[0]);
                }
            }
        }
        let free = |h: bool, m: f64| if h { 0.0 } else { m };
        let m_inv: Vec<f64> = bodies
            .iter()
            .zip(&held)
            .flat_map(|(b, h)| [free(h[0], b.inv_mass), free(h[1], b.inv_mass), b.inv_inertia])
            .collect();
        let w = |p: usize, q: usize| (0..3 * nb).map(|d| b[p][d] * m_inv[d] * b[q][d]).sum::<f64>();
        let assembled = op.assemble();
        for q in 0..2 * nc {
            let mut e = vec![0.0; 2 * nc];
            e[q] = 1.0;
            let mut column = vec![0.0; 2 * nc];
            op.apply(&e, &mut column);
            let mut stored = vec![0.0; 2 * nc];
            assembled.apply(&e, &mut stored);
            for p in 0..2 * nc {
                let dense = w(p, q);
                assert!((column[p] - dense).abs() < 1e-12, "W[{p},{q}]: product {} vs {dense}", column[p]);
                assert!((stored[p] - dense).abs() < 1e-12, "W[{p},{q}]: assembled {} vs {dense}", stored[p]);
            }
        }
        for (a, block) in op.diag_blocks().iter().enumerate() {
            let dense = [w(2 * a, 2 * a), w(2 * a, 2 * a + 1), w(2 * a + 1, 2 * a), w(2 * a + 1, 2 * a + 1)];
            assert!(
                block.iter().zip(&dense).all(|(x, y)| (x - y).abs() < 1e-12),
                "contact {a}: {block:?} vs {dense:?}"
            );
        }
    }

    /// A long row of disks, its contacts checked and built on threads: the rows and levers of one
    /// thread, and of bad contacts the first named (a later one on another thread is not).
    #[test]
    fn contacts_checked_and_built_on_threads_name_the_first_bad_one() {
        let n = 3 * crate::parallel::PARALLEL_MIN;
        let bodies = vec![Body::dynamic(1.0, 0.5); n + 1];
        let contact = |a: usize| {
            let angle = a as f64 * 0.37;
            let normal = [angle.cos(), angle.sin()];
            Contact { i: a + 1, j: Some(a), normal, lever_i: [-normal[0], -normal[1]], lever_j: normal }
        };
        let on = |threads: usize, bad: &(dyn Fn(usize) -> Option<Contact> + Sync)| {
            let build = || MatrixFree::from_contacts(bodies.clone(), n, |a| bad(a).unwrap_or(contact(a)), Dofs::ALL);
            rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap().install(build)
        };
        let (one, two) = (on(1, &|_| None).unwrap(), on(2, &|_| None).unwrap());
        assert_eq!((one.rows.len(), one.levers.len()), (n, n));
        assert!(one.rows.iter().zip(&two.rows).all(|(x, y)| x.i == y.i && x.j == y.j && x.n == y.n));
        assert_eq!(one.levers, two.levers);
        let at = [2 * n / 3, n / 2, n - 1];
        let bad = |a: usize| match a {
            _ if a == at[0] => Some(Contact { normal: [2.0, 0.0], ..contact(a) }),
            _ if a == at[1] => Some(Contact { j: Some(n + 7), ..contact(a) }),
            _ if a == at[2] => Some(Contact { lever_i: [f64::NAN, 0.0], ..contact(a) }),
            _ => None,
        };
        for threads in [1, 2] {
            let e = on(threads, &bad).expect_err("bad contacts");
            assert!(e.starts_with(&format!("contact {}: bodies", at[1])), "{threads} thread(s): {e}");
        }
        let later = |a: usize| bad(a).filter(|_| a != at[1]);
        assert!(on(2, &later).expect_err("bad").contains("is not a unit vector"));
    }

    /// Contact 0 joins disks 1 (i) and 0 (j): disk 1 touches contacts 0, 1 and its floor 8, disk
    /// 0 contacts 0 and its floor 7. A floor contact's fixed side adds nothing, and a disk made
    /// fixed drops out of every row.
    #[test]
    fn a_contacts_neighbours_are_the_contacts_of_its_moving_bodies_each_once() {
        let op = disks_in_a_row();
        // `of` and `for_each` list the same row, from the table and from the bodies' lists.
        let row = |op: &MatrixFree, a: usize| {
            let mut each = Vec::new();
            op.neighbours().for_each(a, |c| each.push(c));
            assert_eq!(each, op.neighbours().of(a).collect::<Vec<_>>());
            // The bodies' lists repeat the contacts both bodies touch.
            let mut from_bodies = Vec::new();
            op.neighbours_from_bodies().for_each(a, |c| {
                if !from_bodies.contains(&c) {
                    from_bodies.push(c)
                }
            });
            assert_eq!(from_bodies, each, "contact {a}");
            each
        };
        assert!(op.neighbours().tabled());
        assert_eq!(row(&op, 0), [0, 1, 8, 7]);
        assert_eq!(row(&op, 7), [0, 7]);
        assert_eq!(row(&op, 3), [3, 4, 11, 2, 10]);
        let mut bodies = op.bodies.clone();
        bodies[1] = Body::fixed();
        let pinned = MatrixFree { bodies, ..disks_in_a_row() };
        assert_eq!(row(&pinned, 0), [0, 7]);
        assert_eq!(row(&pinned, 8), Vec::<usize>::new());
    }

    /// A table handed in is the one the operator serves (a step's operator gets last step's).
    #[test]
    fn a_neighbour_table_handed_in_is_served() {
        let (op, next) = (disks_in_a_row(), disks_in_a_row());
        assert!(op.neighbours_if_built().is_none(), "built on first use only");
        op.neighbours();
        let table = op.neighbours_if_built().expect("built");
        next.give_neighbours(table.clone());
        assert!(next.neighbours_if_built().is_some_and(|t| Arc::ptr_eq(&t, &table)));
        let row = |op: &MatrixFree| op.neighbours().of(3).collect::<Vec<_>>();
        assert_eq!(row(&next), row(&op));
    }

    /// A moving body under 40 grains would put 40 entries in each of its contacts' rows (1,600
    /// in all, against 32 a contact): no table, and the bodies' lists give the same contacts in
    /// the same order, the contact itself twice.
    #[test]
    fn a_body_with_many_contacts_keeps_no_neighbour_table() {
        let bodies = vec![Body::dynamic(1.0, 0.5); 41];
        let contacts: Vec<Contact> = (1..41)
            .map(|i| Contact { i, j: Some(0), normal: [0.0, 1.0], lever_i: [0.0, -1.0], lever_j: [0.0, 1.0] })
            .collect();
        let op = MatrixFree::new(bodies, &contacts).unwrap();
        let neighbours = op.neighbours();
        assert!(!neighbours.tabled());
        let row: Vec<usize> = neighbours.of(5).collect();
        assert_eq!(row, [5].into_iter().chain(0..40).collect::<Vec<_>>());
    }
}
