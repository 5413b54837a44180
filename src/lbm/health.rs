//! Numerical health of the fluid: non-finite values and the Mach number.

use std::fmt;

/// Outcome of [`crate::lbm::Fluid::health`]. The solver never clamps: the caller decides what
/// to do (the CLI stops the run and keeps the last good checkpoint).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Health {
    /// First node (lowest index) with a non-finite population or non-positive density.
    pub first_bad: Option<[usize; 3]>,
    /// Number of such nodes.
    pub bad_nodes: usize,
    /// Largest Mach number `|u|/c_s` over finite nodes.
    pub max_mach: f64,
    /// Where it occurs.
    pub max_mach_at: [usize; 3],
    /// The limit the scan was made against.
    pub mach_limit: f64,
}

impl Health {
    pub(crate) fn note_nonfinite(&mut self, node: [usize; 3]) {
        if self.first_bad.is_none() {
            self.first_bad = Some(node);
        }
        self.bad_nodes += 1;
    }

    pub(crate) fn note_mach(&mut self, mach: f64, node: [usize; 3]) {
        if mach > self.max_mach {
            self.max_mach = mach;
            self.max_mach_at = node;
        }
    }

    /// Merges a later block of nodes (in index order) into this one.
    pub(crate) fn merge(&mut self, o: Health) {
        if self.first_bad.is_none() {
            self.first_bad = o.first_bad;
        }
        self.bad_nodes += o.bad_nodes;
        if o.max_mach > self.max_mach {
            self.max_mach = o.max_mach;
            self.max_mach_at = o.max_mach_at;
        }
    }

    /// True when every node is finite and below the Mach limit.
    pub fn is_ok(&self) -> bool {
        self.first_bad.is_none() && self.max_mach <= self.mach_limit
    }
}

impl fmt::Display for Health {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if let Some(n) = self.first_bad {
            write!(
                f,
                "{} node(s) with non-finite populations or non-positive density, first at (x, y, z) = {:?}",
                self.bad_nodes, n
            )?;
            if self.max_mach > self.mach_limit {
                write!(f, "; ")?;
            }
        }
        if self.max_mach > self.mach_limit {
            write!(
                f,
                "Mach number {:.3} at (x, y, z) = {:?} exceeds the limit {:.3} (lower the velocity scale or refine)",
                self.max_mach, self.max_mach_at, self.mach_limit
            )?;
        }
        if self.is_ok() {
            write!(f, "healthy (max Mach {:.4} at {:?})", self.max_mach, self.max_mach_at)?;
        }
        Ok(())
    }
}
