//! A periodic cell along x: a grain that leaves at `x1` comes back at `x0`, and grains on either
//! side of the boundary touch through it (detection pairs a grain with the image of another
//! shifted by ± the cell's length).

/// The cell `[x0, x1)` along x; y is unbounded.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Periodic {
    /// Left end of the cell (m).
    pub x0: f64,
    /// Right end of the cell (m).
    pub x1: f64,
}

impl Periodic {
    /// Refuses a cell that is not finite or has no length.
    pub fn new(x0: f64, x1: f64) -> Result<Self, String> {
        if !(x0.is_finite() && x1.is_finite() && x1 > x0) {
            return Err(format!("[{x0}, {x1}] must be finite with x0 < x1"));
        }
        Ok(Self { x0, x1 })
    }

    /// The cell's length x1 − x0.
    pub fn length(&self) -> f64 {
        self.x1 - self.x0
    }

    /// `x` brought into `[x0, x1)`.
    #[inline]
    pub fn wrap(&self, x: f64) -> f64 {
        let w = self.x0 + (x - self.x0).rem_euclid(self.length());
        // rem_euclid may round up to the length itself.
        if w >= self.x1 {
            self.x0
        } else {
            w
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn positions_wrap_into_the_cell() {
        let p = Periodic::new(-1.0, 3.0).unwrap();
        assert_eq!(p.wrap(3.5), -0.5);
        assert_eq!(p.wrap(-1.5), 2.5);
        assert_eq!(p.wrap(1.0), 1.0);
        assert_eq!(p.wrap(3.0), -1.0);
        assert!((-1.0..3.0).contains(&p.wrap(-1e-17)));
        assert!(Periodic::new(1.0, 1.0).is_err() && Periodic::new(0.0, f64::NAN).is_err());
    }
}
