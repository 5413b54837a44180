//! What a valid case holds, for people: [`Case::describe`], printed by `slurry check`.

use std::fmt::Write as _;

use super::memory::{available_memory, fmt_bytes, MemoryEstimate};
use super::{mach, BoundarySpec, Case, InitialKind};
use crate::lattice::{Face, CS2, Q};
use crate::lbm::Collision;
use crate::rigid::impeller::{ImpellerKind, Pumping};
use crate::util::fmt_num;

impl Case {
    /// A summary of everything the case holds, one line per item, for a valid case: the grid
    /// and the memory of its populations, the fluid, the body force, the six faces, the
    /// initial state, with particles gravity, the IBM settings, each `[[particles]]` and
    /// `[[random_particles]]` entry and the placed solids fraction, the impeller, the
    /// contacts, the memory estimate against what the machine has, and the run.
    pub fn describe(&self) -> String {
        let mut s = String::new();
        self.describe_fluid(&mut s);
        if self.has_particles() {
            self.describe_particles(&mut s);
        }
        self.describe_impeller(&mut s);
        self.describe_contacts(&mut s);
        let estimate = MemoryEstimate::of(self);
        let limit = available_memory()
            .map(|l| format!("{} available ({})", fmt_bytes(l.bytes), l.source))
            .unwrap_or_else(|| "available memory unknown".into());
        let _ = writeln!(s, "memory      about {}; {limit}", estimate.describe());
        let _ = writeln!(
            s,
            "run         {} steps, output every {} ({} rows), Mach limit {}",
            self.run.steps,
            self.run.output_every,
            self.output_rows(),
            self.run.mach_limit
        );
        s
    }

    /// Grid, fluid, body force, faces and the initial state.
    fn describe_fluid(&self, s: &mut String) {
        let grid = self.grid();
        let padded_nodes = (grid.nx + 2) * (grid.ny + 2) * (grid.nz + 2);
        let population_bytes = padded_nodes * Q * self.fluid.precision.bytes();
        let _ = writeln!(
            s,
            "grid        {} x {} x {} = {} nodes ({} precision, ~{:.1} MiB of populations)",
            grid.nx,
            grid.ny,
            grid.nz,
            grid.nodes(),
            self.fluid.precision.name(),
            population_bytes as f64 / (1024.0 * 1024.0)
        );
        let params = self.fluid_params();
        let model = match params.collision {
            Collision::Bgk => "BGK".to_string(),
            Collision::Trt { magic } => format!("TRT (magic {magic})"),
        };
        let _ = writeln!(s, "fluid       nu = {}, tau = {}, {model}", params.nu, params.tau());
        let force = params.body_force;
        let _ = writeln!(s, "body force  [{}, {}, {}]", force[0], force[1], force[2]);
        for face in Face::ALL {
            let boundary = self.boundaries.get(face);
            let _ = write!(s, "{:<11} {boundary}", face.name());
            if let BoundarySpec::MovingWall(v) = boundary {
                let _ = write!(s, "  (wall Mach {:.4})", mach(v));
            }
            s.push('\n');
        }
        match self.initial.kind {
            InitialKind::Uniform => {
                let v = self.initial.velocity.unwrap_or([0.0; 3]);
                let _ = writeln!(
                    s,
                    "initial     uniform, density {}, velocity [{}, {}, {}]",
                    self.initial.density, v[0], v[1], v[2]
                );
            }
            InitialKind::TaylorGreen => {
                let _ = writeln!(
                    s,
                    "initial     Taylor-Green, density {}, amplitude {}",
                    self.initial.density,
                    self.initial.amplitude.unwrap_or(0.0)
                );
            }
        }
    }

    /// Gravity, the IBM settings, each particle entry and the solids fraction once placed.
    fn describe_particles(&self, s: &mut String) {
        let gravity = self.gravity();
        let _ = writeln!(s, "gravity     [{}, {}, {}]", gravity[0], gravity[1], gravity[2]);
        let ibm = self.ibm();
        let _ = writeln!(
            s,
            "ibm         {} kernel, {} forcing iteration(s), marker spacing {}",
            ibm.kernel.name(),
            ibm.iterations,
            ibm.marker_spacing
        );
        for (i, p) in self.particles.iter().enumerate() {
            let _ = writeln!(
                s,
                "particle    [{i}] {} d {}{}, density {}, at [{}, {}, {}], {}",
                p.shape.name(),
                p.diameter,
                p.length.map(|l| format!(" l {l}")).unwrap_or_default(),
                p.density,
                p.position[0],
                p.position[1],
                p.position[2],
                p.motion.name()
            );
        }
        for (k, r) in self.random_particles.iter().enumerate() {
            let _ = writeln!(
                s,
                "random      [{k}] {} x {} d {}{}, density {}, seed {}, clearance {}, {}",
                self.random_count(k),
                r.shape.name(),
                r.diameter,
                r.length.map(|l| format!(" l {l}")).unwrap_or_default(),
                r.density,
                r.seed,
                r.clearance,
                r.motion.name()
            );
        }
        if let Ok(inits) = self.particle_inits() {
            let solids_volume: f64 = inits.iter().map(|p| p.volume()).sum();
            let box_volume = self.grid().nodes() as f64;
            let _ = writeln!(
                s,
                "particles   {} in all, solids volume fraction {:.4} of the box",
                inits.len(),
                solids_volume / box_volume
            );
        }
    }

    /// The impeller, its dimensions resolved from the defaults, and its rotation.
    fn describe_impeller(&self, s: &mut String) {
        let Ok(Some(setup)) = self.impeller_setup() else { return };
        let geometry = setup.shape.geometry();
        let kind = match geometry.kind {
            ImpellerKind::Disk { thickness } => format!("disk, thickness {}", fmt_num(thickness)),
            ImpellerKind::PitchedBlade {
                blades,
                pitch,
                blade_width,
                blade_thickness,
                hub_diameter,
                hub_height,
                pumping,
            } => format!(
                "pitched-blade turbine, {blades} blades at {}°, width {}, thickness {}, hub {} x {}, \
                 pumping {}",
                fmt_num(pitch.to_degrees()),
                fmt_num(blade_width),
                fmt_num(blade_thickness),
                fmt_num(hub_diameter),
                fmt_num(hub_height),
                match pumping {
                    Pumping::Down => "down",
                    Pumping::Up => "up",
                }
            ),
        };
        let shaft = if geometry.shaft_length > 0.0 {
            format!("shaft d {} to the lid", fmt_num(geometry.shaft_diameter))
        } else {
            "no shaft".to_string()
        };
        let centre = setup.centre.map(fmt_num);
        let _ = writeln!(
            s,
            "impeller    {kind}; D {}, centre [{}, {}, {}], {shaft}",
            fmt_num(setup.diameter()),
            centre.x,
            centre.y,
            centre.z
        );
        let _ = writeln!(
            s,
            "rotation    N = {} rev/step ({} steps per revolution), ramp {} steps, tip speed {} (Mach {:.4})",
            fmt_num(setup.speed()),
            fmt_num(1.0 / setup.speed().abs()),
            setup.motion.ramp_steps,
            fmt_num(setup.tip_speed()),
            setup.tip_speed() / CS2.sqrt()
        );
    }

    /// The contact parameters (Table 1 unless changed) and the sub-steps.
    fn describe_contacts(&self, s: &mut String) {
        let Some(p) = &self.contacts else { return };
        let on = |b: bool| if b { "on" } else { "off" };
        let _ = writeln!(
            s,
            "contacts    k {}, δ0 {}, λ {}, kⁿ {}, δ_d {}, δ_sat {}, kᵗ {}; elastic {}, lubrication {}; \
             {} sub-steps per step{}",
            p.k,
            p.delta0,
            p.lambda,
            p.k_n,
            p.delta_d,
            p.delta_sat,
            p.k_t,
            on(p.elastic),
            on(p.lubrication),
            p.substeps,
            match (p.damping, p.lubrication_limiter, p.lubrication_substeps) {
                (crate::contact::Damping::Implicit, _, _) =>
                    ", damping implicit (backward Euler, one sparse solve per sub-step)".to_string(),
                (_, true, _) => ", lubrication limiter on".to_string(),
                (_, false, 1) => String::new(),
                (_, false, m) => format!(", {m} lubrication sub-steps each"),
            }
        );
    }
}
