//! The box of lattice nodes and its six faces.

use serde::{Deserialize, Serialize};

/// A box of `nx × ny × nz` nodes, stored x fastest: `index = x + nx·(y + ny·z)`.
///
/// With half-way bounce-back walls the physical wall lies half a spacing outside the
/// outermost nodes, so the box spans `[-½, n - ½]` in each walled direction.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Grid {
    /// Nodes along x.
    pub nx: usize,
    /// Nodes along y.
    pub ny: usize,
    /// Nodes along z.
    pub nz: usize,
}

impl Grid {
    /// A grid of the given size.
    pub fn new(nx: usize, ny: usize, nz: usize) -> Self {
        Self { nx, ny, nz }
    }

    /// Number of nodes.
    pub fn nodes(&self) -> usize {
        self.nx * self.ny * self.nz
    }

    /// Linear index of node `(x, y, z)`.
    #[inline(always)]
    pub fn index(&self, x: usize, y: usize, z: usize) -> usize {
        x + self.nx * (y + self.ny * z)
    }

    /// Coordinates of the node with linear index `i`.
    #[inline]
    pub fn coords(&self, i: usize) -> [usize; 3] {
        [i % self.nx, (i / self.nx) % self.ny, i / (self.nx * self.ny)]
    }

    /// Size along axis `a` (0 = x, 1 = y, 2 = z).
    #[inline(always)]
    pub fn dim(&self, a: usize) -> usize {
        [self.nx, self.ny, self.nz][a]
    }
}

/// The linear index of node `(x, y, z)` in some array: `base + x + sy·y + sz·z`. The interior
/// order of a [`Grid`] is `(0, nx, nx·ny)`; the fluid's padded arrays have their own
/// (`crate::lbm::Fluid::padded_layout`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct NodeLayout {
    /// Index of node `(0, 0, 0)`.
    pub base: usize,
    /// Index step per `y`.
    pub sy: usize,
    /// Index step per `z`.
    pub sz: usize,
}

impl NodeLayout {
    /// Index of node `(x, y, z)`.
    #[inline(always)]
    pub fn index(&self, x: usize, y: usize, z: usize) -> usize {
        self.base + x + self.sy * y + self.sz * z
    }
}

impl Grid {
    /// The interior layout `x + nx (y + ny z)` (what [`Grid::index`] computes).
    pub fn layout(&self) -> NodeLayout {
        NodeLayout { base: 0, sy: self.nx, sz: self.nx * self.ny }
    }
}

/// A run of consecutive nodes along x: `(x0 .. x0 + len, y, z)`, all inside the grid.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct Run {
    /// First x.
    pub x0: u32,
    /// Number of nodes (≥ 1).
    pub len: u32,
    /// Row y.
    pub y: u32,
    /// Plane z.
    pub z: u32,
}

/// One of the six faces of the box.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Face {
    /// x = 0 side.
    XMin,
    /// x = nx − 1 side.
    XMax,
    /// y = 0 side.
    YMin,
    /// y = ny − 1 side.
    YMax,
    /// z = 0 side (the floor).
    ZMin,
    /// z = nz − 1 side (the lid).
    ZMax,
}

impl Face {
    /// All faces, in the order used by [`crate::lbm::Boundaries`].
    pub const ALL: [Face; 6] = [Face::XMin, Face::XMax, Face::YMin, Face::YMax, Face::ZMin, Face::ZMax];

    /// The axis normal to this face (0 = x, 1 = y, 2 = z).
    pub fn axis(self) -> usize {
        self as usize / 2
    }

    /// Whether this is the low (`min`) face of its axis.
    pub fn is_min(self) -> bool {
        (self as usize).is_multiple_of(2)
    }

    /// The face with the given axis and side.
    pub fn from_axis(axis: usize, min: bool) -> Face {
        Face::ALL[2 * axis + usize::from(!min)]
    }

    /// Name as used in case files (`x_min`, …).
    pub fn name(self) -> &'static str {
        ["x_min", "x_max", "y_min", "y_max", "z_min", "z_max"][self as usize]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn index_and_coords_are_inverse() {
        let g = Grid::new(5, 3, 4);
        for i in 0..g.nodes() {
            let [x, y, z] = g.coords(i);
            assert_eq!(g.index(x, y, z), i);
        }
    }

    #[test]
    fn faces_round_trip() {
        for f in Face::ALL {
            assert_eq!(Face::from_axis(f.axis(), f.is_min()), f);
        }
    }
}
