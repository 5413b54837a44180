//! How much memory a case needs, and how much the machine has: `slurry check` and
//! `slurry run` refuse a case that cannot fit before allocating anything large (without the
//! check, a 600³ f64 grid aborts with `memory allocation of N bytes failed`).
//!
//! [`MemoryEstimate::of`] adds up, in bytes (`N` interior nodes, `P = (nx+2)(ny+2)(nz+2)`
//! padded nodes, `b` bytes per number of the storage precision, `M` surface markers,
//! `n` particles):
//!
//! | part | bytes |
//! |---|---|
//! | populations | `19 b P` |
//! | force field (particles or impeller) | `3 b P` |
//! | node masks (solid, obstacle) | `P + N` |
//! | coupling velocity buffer (particles or impeller) | `24 N` |
//! | coupling's stored momenta of dense steps (particles) | `24 N` |
//! | markers and their stencils | `BYTES_PER_MARKER M` |
//! | particles (bodies, output frame) | `BYTES_PER_PARTICLE n` |
//! | output: the larger of the final fields (`32 N`) and a checkpoint's copy (`19 b N`, `+ 3 b N` with the force field) | |
//!
//! `M` is estimated from each particle's surface area over the squared marker spacing (plus
//! one), and the impeller's likewise. The limit ([`available_memory`]) is `MemAvailable` of
//! `/proc/meminfo`, lowered to the cgroup's `memory.max − memory.current` where there is
//! one; without `/proc/meminfo`, the available physical pages (`sysconf`); lowered again to the
//! address-space limit (`ulimit -v`) less the process's present size where there is one. The environment
//! variable `SLURRY_MEMORY_LIMIT` (bytes, or with a suffix `K`, `M`, `G`, `T`: powers of 1024)
//! replaces it.

use std::path::Path;

use super::particles::{particle_surface_area, ShapeKind};
use super::Case;
use crate::lattice::Q;

/// Bytes per surface marker: the body-frame marker twice (56 each: the coupling keeps the
/// forcing markers, retracted, and the contact markers, on the true surface; the retracted
/// set has fewer markers, so counting the true surface's is an upper bound), the coupling's
/// per-marker arrays (about 130), the stencil (about 160) and the contact engine's bins,
/// rounded up.
pub const BYTES_PER_MARKER: u64 = 512;
/// Bytes per particle: the rigid body, its loads and states, a frame of `particles.h5`.
pub const BYTES_PER_PARTICLE: u64 = 1024;
/// The environment variable that replaces the machine's available memory.
pub const LIMIT_ENV: &str = "SLURRY_MEMORY_LIMIT";

/// The memory a case needs, by part (bytes).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MemoryEstimate {
    /// Populations `19 b P`.
    pub populations: u64,
    /// Force field `3 b P` (0 without particles and impeller).
    pub force: u64,
    /// Node masks and the coupling's grid-sized velocity buffer.
    pub grid_other: u64,
    /// Markers and stencils.
    pub markers: u64,
    /// Number of markers (estimate).
    pub marker_count: f64,
    /// Particles.
    pub particles: u64,
    /// The larger of the final fields and a checkpoint's copy of the state.
    pub output: u64,
}

impl MemoryEstimate {
    /// The estimate for `case` (module docs). Cheap: nothing is placed or allocated, and
    /// every count is taken in floating point (no overflow).
    pub fn of(case: &Case) -> MemoryEstimate {
        let d = &case.domain;
        let nodes = d.nx as f64 * d.ny as f64 * d.nz as f64;
        let padded = (d.nx as f64 + 2.0) * (d.ny as f64 + 2.0) * (d.nz as f64 + 2.0);
        let b = case.fluid.precision.bytes() as f64;
        let coupled = case.has_particles() || case.impeller.is_some();
        let spacing = case.ibm().marker_spacing;
        let markers_of = |shape: ShapeKind, diameter: f64, length: Option<f64>| {
            let area = particle_surface_area(shape, diameter, length);
            if area.is_finite() {
                area / (spacing * spacing) + 1.0
            } else {
                0.0
            }
        };
        let mut marker_count = 0.0;
        let mut particles = 0.0;
        for p in &case.particles {
            marker_count += markers_of(p.shape, p.diameter, p.length);
            particles += 1.0;
        }
        for (k, r) in case.random_particles.iter().enumerate() {
            let n = case.random_count_f64(k);
            marker_count += n * markers_of(r.shape, r.diameter, r.length);
            particles += n;
        }
        if let Ok(Some(imp)) = case.impeller_setup() {
            marker_count += crate::rigid::Shape::surface_area(&*imp.shape) / (spacing * spacing) + 1.0;
        }
        let force = if coupled { 3.0 * b * padded } else { 0.0 };
        let checkpoint = if case.run.checkpoint_every.is_some() {
            (Q as f64 + if coupled { 3.0 } else { 0.0 }) * b * nodes
        } else {
            0.0
        };
        let to = |x: f64| if x.is_finite() && x < u64::MAX as f64 { x as u64 } else { u64::MAX };
        MemoryEstimate {
            populations: to(Q as f64 * b * padded),
            force: to(force),
            grid_other: to(padded
                + nodes
                + if coupled { 24.0 * nodes } else { 0.0 }
                + if case.has_particles() { 24.0 * nodes } else { 0.0 }),
            markers: to(BYTES_PER_MARKER as f64 * marker_count),
            marker_count,
            particles: to(BYTES_PER_PARTICLE as f64 * particles),
            output: to((32.0 * nodes).max(checkpoint)),
        }
    }

    /// The sum of the parts.
    pub fn total(&self) -> u64 {
        [self.populations, self.force, self.grid_other, self.markers, self.particles, self.output]
            .iter()
            .fold(0u64, |a, &x| a.saturating_add(x))
    }

    /// The grid's share (populations, force field, masks, output).
    pub fn grid_part(&self) -> u64 {
        [self.populations, self.force, self.grid_other, self.output]
            .iter()
            .fold(0u64, |a, &x| a.saturating_add(x))
    }

    /// One line: the total and its parts (those that are not zero).
    pub fn describe(&self) -> String {
        let mut parts = vec![format!("populations {}", fmt_bytes(self.populations))];
        if self.force > 0 {
            parts.push(format!("force field {}", fmt_bytes(self.force)));
        }
        if self.markers > 0 {
            parts.push(format!(
                "{} markers {}",
                crate::util::fmt_num(self.marker_count.round()),
                fmt_bytes(self.markers)
            ));
        }
        if self.particles > 0 {
            parts.push(format!("particles {}", fmt_bytes(self.particles)));
        }
        parts.push(format!("fields/checkpoint output {}", fmt_bytes(self.output)));
        format!("{} ({})", fmt_bytes(self.total()), parts.join(", "))
    }
}

/// Bytes in binary units with 3 significant digits (`1.50 GiB`).
pub fn fmt_bytes(b: u64) -> String {
    const UNITS: [&str; 7] = ["B", "KiB", "MiB", "GiB", "TiB", "PiB", "EiB"];
    let mut v = b as f64;
    let mut u = 0;
    while v >= 1024.0 && u + 1 < UNITS.len() {
        v /= 1024.0;
        u += 1;
    }
    if u == 0 {
        format!("{b} B")
    } else {
        format!("{v:.3} {}", UNITS[u])
    }
}

/// The memory this process may use, and where the figure comes from.
#[derive(Clone, Debug, PartialEq)]
pub struct MemoryLimit {
    /// Bytes.
    pub bytes: u64,
    /// Where it comes from (e.g. `MemAvailable in /proc/meminfo`).
    pub source: String,
}

/// Parses `SLURRY_MEMORY_LIMIT`-style sizes: bytes, or a number with `K`, `M`, `G` or `T`
/// (powers of 1024; an optional `iB`/`B` after it).
pub fn parse_size(text: &str) -> Option<u64> {
    let t = text.trim();
    let t = t.strip_suffix("iB").or_else(|| t.strip_suffix('B')).unwrap_or(t);
    let (num, mult) = match t.chars().last()? {
        'k' | 'K' => (&t[..t.len() - 1], 1u64 << 10),
        'm' | 'M' => (&t[..t.len() - 1], 1 << 20),
        'g' | 'G' => (&t[..t.len() - 1], 1 << 30),
        't' | 'T' => (&t[..t.len() - 1], 1 << 40),
        _ => (t, 1),
    };
    let v: f64 = num.trim().parse().ok()?;
    (v.is_finite() && v >= 0.0).then(|| (v * mult as f64).min(u64::MAX as f64) as u64)
}

/// A `kB` value of `/proc/meminfo`.
fn meminfo(text: &str, key: &str) -> Option<u64> {
    let line = text.lines().find(|l| l.starts_with(key) && l[key.len()..].starts_with(':'))?;
    let kb: u64 = line[key.len() + 1..].trim().trim_end_matches("kB").trim().parse().ok()?;
    Some(kb.saturating_mul(1024))
}

/// The cgroup (v2) headroom `memory.max − memory.current`, if this process has a limit.
fn cgroup_headroom() -> Option<u64> {
    let base = Path::new("/sys/fs/cgroup");
    let max: u64 = std::fs::read_to_string(base.join("memory.max")).ok()?.trim().parse().ok()?;
    let current: u64 = std::fs::read_to_string(base.join("memory.current")).ok()?.trim().parse().ok()?;
    Some(max.saturating_sub(current))
}

/// The memory available to this process (module docs); `None` when nothing tells.
pub fn available_memory() -> Option<MemoryLimit> {
    if let Ok(v) = std::env::var(LIMIT_ENV) {
        if let Some(bytes) = parse_size(&v) {
            return Some(MemoryLimit { bytes, source: format!("{LIMIT_ENV}={v}") });
        }
    }
    let from_meminfo = std::fs::read_to_string("/proc/meminfo")
        .ok()
        .and_then(|t| meminfo(&t, "MemAvailable").or_else(|| meminfo(&t, "MemFree")))
        .map(|bytes| MemoryLimit { bytes, source: "MemAvailable in /proc/meminfo".into() })
        .or_else(sysconf_available);
    let physical = match (from_meminfo, cgroup_headroom()) {
        (Some(m), Some(c)) if c < m.bytes => {
            Some(MemoryLimit { bytes: c, source: "the cgroup's memory.max less memory.current".into() })
        }
        (Some(m), _) => Some(m),
        (None, Some(c)) => {
            Some(MemoryLimit { bytes: c, source: "the cgroup's memory.max less memory.current".into() })
        }
        (None, None) => None,
    };
    match (physical, address_space_headroom()) {
        (Some(m), Some(a)) if a >= m.bytes => Some(m),
        (_, Some(a)) => Some(MemoryLimit {
            bytes: a,
            source: "the address-space limit (ulimit -v) less this process's present size".into(),
        }),
        (m, None) => m,
    }
}

/// The address-space limit (`ulimit -v`, `RLIMIT_AS`) less this process's present size
/// (`VmSize` of `/proc/self/status`), if there is a limit: past it an allocation fails and the
/// process aborts, whatever the physical memory.
#[cfg(target_os = "linux")]
fn address_space_headroom() -> Option<u64> {
    let mut r = libc::rlimit { rlim_cur: 0, rlim_max: 0 };
    // SAFETY: getrlimit writes the one struct it is given.
    if unsafe { libc::getrlimit(libc::RLIMIT_AS, &mut r) } != 0 || r.rlim_cur == libc::RLIM_INFINITY {
        return None;
    }
    let size =
        std::fs::read_to_string("/proc/self/status").ok().and_then(|t| meminfo(&t, "VmSize")).unwrap_or(0);
    Some(r.rlim_cur.saturating_sub(size))
}

/// No address-space limit is read on other platforms.
#[cfg(not(target_os = "linux"))]
fn address_space_headroom() -> Option<u64> {
    None
}

/// Available physical pages times the page size (platforms without `/proc/meminfo`).
#[cfg(target_os = "linux")]
fn sysconf_available() -> Option<MemoryLimit> {
    // SAFETY: sysconf has no preconditions.
    let (pages, size) = unsafe { (libc::sysconf(libc::_SC_AVPHYS_PAGES), libc::sysconf(libc::_SC_PAGESIZE)) };
    (pages > 0 && size > 0).then(|| MemoryLimit {
        bytes: (pages as u64).saturating_mul(size as u64),
        source: "available physical pages (sysconf)".into(),
    })
}

/// Available physical pages times the page size (platforms without `/proc/meminfo`).
#[cfg(not(target_os = "linux"))]
fn sysconf_available() -> Option<MemoryLimit> {
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_and_meminfo_parse() {
        assert_eq!(parse_size("1024"), Some(1024));
        assert_eq!(parse_size("2G"), Some(2 << 30));
        assert_eq!(parse_size("1.5MiB"), Some(3 << 19));
        assert_eq!(parse_size("x"), None);
        let t = "MemTotal:       16000000 kB\nMemFree: 10 kB\nMemAvailable:    8000000 kB\n";
        assert_eq!(meminfo(t, "MemAvailable"), Some(8_000_000 * 1024));
        assert_eq!(fmt_bytes(3 << 30), "3.000 GiB");
    }
}
