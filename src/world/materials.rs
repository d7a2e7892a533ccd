//! Materials (density) and the contact law parameters of each pair of materials.

/// Contact law parameters of one pair of materials.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Interaction {
    /// Coulomb coefficient μ.
    pub friction: f64,
    /// Newton restitution coefficient e in [0, 1].
    pub restitution: f64,
    /// Cohesion: the impulse per step a bond can hold.
    pub cohesion: f64,
    /// η: the rolling resistance torque is at most η R r_n (R the contact's rolling radius).
    pub rolling_resistance: f64,
}

/// Material names, densities and a symmetric table of interactions.
#[derive(Clone, Debug, Default)]
pub struct Materials {
    /// Material names, as scenes refer to them.
    pub names: Vec<String>,
    /// Densities (kg/m² in 2D).
    pub density: Vec<f64>,
    table: Vec<Interaction>,
    /// Pairs of materials whose bodies pass through each other (n × n; empty while none do).
    passing: Vec<bool>,
}

impl Materials {
    /// Materials with one default interaction for every pair.
    pub fn new(names: Vec<String>, density: Vec<f64>, default: Interaction) -> Self {
        let n = names.len();
        Self { names, density, table: vec![default; n * n], passing: Vec::new() }
    }

    /// Number of materials.
    pub fn len(&self) -> usize {
        self.names.len()
    }

    /// Whether there is no material.
    pub fn is_empty(&self) -> bool {
        self.names.is_empty()
    }

    /// The index of the material called `name`.
    pub fn index_of(&self, name: &str) -> Option<usize> {
        self.names.iter().position(|n| n == name)
    }

    /// Sets the law between materials `a` and `b` (both ways).
    pub fn set(&mut self, a: usize, b: usize, law: Interaction) {
        let n = self.len();
        self.table[a * n + b] = law;
        self.table[b * n + a] = law;
    }

    /// The law between materials `a` and `b`.
    #[inline]
    pub fn interaction(&self, a: usize, b: usize) -> Interaction {
        self.table[a * self.len() + b]
    }

    /// Makes the bodies (and walls) of materials `a` and `b` pass through each other, or touch
    /// again: no contact is detected between them (LMGC90's visibility table), as for the plates
    /// of a biaxial box that cross at its corners.
    pub fn set_pass_through(&mut self, a: usize, b: usize, through: bool) {
        let n = self.len();
        if self.passing.is_empty() {
            if !through {
                return;
            }
            self.passing = vec![false; n * n];
        }
        self.passing[a * n + b] = through;
        self.passing[b * n + a] = through;
    }

    /// Whether the bodies of materials `a` and `b` pass through each other.
    #[inline]
    pub fn pass_through(&self, a: usize, b: usize) -> bool {
        !self.passing.is_empty() && self.passing[a * self.len() + b]
    }

    /// Whether some pair of materials passes through each other.
    pub fn any_pass_through(&self) -> bool {
        self.passing.contains(&true)
    }

    /// Largest friction coefficient of any pair (to tell whether friction could matter).
    pub fn max_friction(&self) -> f64 {
        self.table.iter().map(|l| l.friction).fold(0.0, f64::max)
    }
    /// Largest restitution coefficient of any pair.
    pub fn max_restitution(&self) -> f64 {
        self.table.iter().map(|l| l.restitution).fold(0.0, f64::max)
    }
    /// Largest cohesion of any pair.
    pub fn max_cohesion(&self) -> f64 {
        self.table.iter().map(|l| l.cohesion).fold(0.0, f64::max)
    }
    /// Largest rolling-resistance coefficient of any pair.
    pub fn max_rolling_resistance(&self) -> f64 {
        self.table.iter().map(|l| l.rolling_resistance).fold(0.0, f64::max)
    }
}
