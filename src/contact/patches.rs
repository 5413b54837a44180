//! Static body-frame patches of a body's markers: the coarse level of the narrow phase (module
//! [`super`], "Narrow phase").

use crate::rigid::{Marker, Vec3};

use super::grid::{fill, for_cells, Geometry};

/// Edge of the cubes that group a body's markers into patches (lattice units): a patch of a
/// surface holds ≈ 8 markers at spacing 0.7.
pub(crate) const PATCH_EDGE: f64 = 2.0;

/// Static patches of one body's markers (body frame, built once): the markers binned into
/// cubes of edge [`PATCH_EDGE`]; every non-empty cube is a patch, with the bounding sphere of
/// its markers. A query prunes whole patches with one signed-distance evaluation (module
/// [`super`], "Narrow phase").
#[derive(Clone, Debug)]
pub(crate) struct Patches {
    geo: Geometry,
    /// Per grid cell: its patch, or `u32::MAX` if empty.
    cell_patch: Vec<u32>,
    pub(crate) centre: Vec<Vec3>,
    pub(crate) radius: Vec<f64>,
    /// Patch `k` holds the markers `items[start[k]..start[k + 1]]` (increasing index).
    start: Vec<u32>,
    items: Vec<u32>,
    /// Centre and half size of the axis-aligned box of all the body's markers (body frame).
    box_centre: Vec3,
    box_half: Vec3,
}

impl Patches {
    pub(crate) fn new(markers: &[Marker]) -> Self {
        let (mut lo, mut hi) = (Vec3::repeat(f64::INFINITY), Vec3::repeat(f64::NEG_INFINITY));
        for m in markers {
            lo = lo.inf(&m.position);
            hi = hi.sup(&m.position);
        }
        if markers.is_empty() {
            (lo, hi) = (Vec3::zeros(), Vec3::zeros());
        }
        let geo = Geometry::covering(&lo, &hi, PATCH_EDGE, 8 * markers.len() + 64);
        let (mut cell_of, mut cell_start, mut items) = (Vec::new(), Vec::new(), Vec::new());
        fill(
            geo.len(),
            markers.len(),
            |k| geo.clamped_index(&markers[k].position),
            &mut cell_of,
            &mut cell_start,
            &mut items,
        );
        let mut p = Self {
            geo,
            cell_patch: vec![u32::MAX; geo.len()],
            centre: Vec::new(),
            radius: Vec::new(),
            start: Vec::new(),
            items,
            box_centre: (lo + hi) * 0.5,
            box_half: (hi - lo) * 0.5,
        };
        for c in 0..geo.len() {
            let range = cell_start[c] as usize..cell_start[c + 1] as usize;
            if range.is_empty() {
                continue;
            }
            let (mut a, mut b) = (Vec3::repeat(f64::INFINITY), Vec3::repeat(f64::NEG_INFINITY));
            for &k in &p.items[range.clone()] {
                a = a.inf(&markers[k as usize].position);
                b = b.sup(&markers[k as usize].position);
            }
            let centre = (a + b) * 0.5;
            let r = p.items[range.clone()]
                .iter()
                .map(|&k| (markers[k as usize].position - centre).norm())
                .fold(0.0, f64::max);
            p.cell_patch[c] = p.centre.len() as u32;
            p.centre.push(centre);
            p.radius.push(r);
            p.start.push(range.start as u32);
        }
        p.start.push(p.items.len() as u32);
        p
    }

    /// Calls `f(k)` for every patch `k` whose bounding sphere meets the ball `|x − p| < rho`
    /// (body frame).
    #[inline(always)]
    pub(crate) fn visit(&self, p: &Vec3, rho: f64, mut f: impl FnMut(usize)) {
        let Some(r) = self.geo.range(p, rho) else { return };
        let mut test = |k: usize| {
            let reach = rho + self.radius[k];
            if (self.centre[k] - p).norm_squared() < reach * reach {
                f(k);
            }
        };
        let cells = (0..3).map(|a| r[a][1] - r[a][0] + 1).product::<usize>();
        if cells > self.centre.len() {
            (0..self.centre.len()).for_each(&mut test);
        } else {
            for_cells(&self.geo, r, |c| {
                let k = self.cell_patch[c];
                if k != u32::MAX {
                    test(k as usize);
                }
            });
        }
    }

    /// Squared distance from `q` (body frame) to the box of the markers: a lower bound of the
    /// squared distance from `q` to every marker of the body.
    #[inline(always)]
    pub(crate) fn box_distance2(&self, q: &Vec3) -> f64 {
        let e = ((q - self.box_centre).abs() - self.box_half).sup(&Vec3::zeros());
        e.norm_squared()
    }

    /// The markers of patch `k`.
    #[inline(always)]
    pub(crate) fn markers(&self, k: usize) -> &[u32] {
        &self.items[self.start[k] as usize..self.start[k + 1] as usize]
    }
}
