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
}

impl Materials {
    /// Materials with one default interaction for every pair.
    pub fn new(names: Vec<String>, density: Vec<f64>, default: Interaction) -> Self {
        let n = names.len();
        Self { names, density, table: vec![default; n * n] }
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
