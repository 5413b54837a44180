//! The coupled time step allocates nothing once warm (issue 3: "marker work must not allocate
//! in the time step"): a counting global allocator around steps of a coupled system with free
//! cylinders, contacts and walls, stepped on a worker of the rayon pool.

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;

use slurry::contact::ContactParams;
use slurry::coupling::{Coupled, CouplingParams};
use slurry::lattice::Grid;
use slurry::lbm::{Boundaries, Fluid, FluidParams};
use slurry::rigid::{Cylinder, Motion, Quat, RigidBody, Vec3};

struct Counting;

static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

// SAFETY: forwards to the system allocator; only counts.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        System.alloc(layout)
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        System.dealloc(ptr, layout)
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        System.realloc(ptr, layout, new_size)
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn warm_coupled_steps_do_not_allocate() {
    let mut fluid =
        Fluid::<f32>::new(Grid::new(32, 32, 40), FluidParams::bgk(0.05), Boundaries::closed_box()).unwrap();
    fluid.initialize(|_, _, _| (1.0, [0.0; 3]));
    // Four horizontal cylinders (axis along y) on the floor, side by side, each within the
    // contact range of the floor and of its neighbours: contacts act during the counted steps.
    let bodies: Vec<RigidBody> = (0..4)
        .map(|k| {
            RigidBody::new(Arc::new(Cylinder::new(6.0, 12.0)), 1.25, Motion::Free)
                .with_position(Vec3::new(5.0 + 6.6 * k as f64, 16.0, 2.9))
                .with_orientation(Quat::from_euler_angles(std::f64::consts::FRAC_PI_2, 0.0, 0.0))
        })
        .collect();
    let params = CouplingParams {
        gravity: [0.0, 0.0, -1e-4],
        contacts: Some(ContactParams::default()),
        ..Default::default()
    };
    let mut c = Coupled::new(fluid, bodies, params).unwrap();
    // On a worker of the pool (as `slurry run` steps): parallel loops then queue their jobs on
    // the worker's own deque. Called from outside the pool, rayon injects each job into its
    // global queue, which allocates a block every 63 jobs (rayon's, not ours).
    rayon::scope(|_| c.run(20)).unwrap(); // warm: every buffer has grown
    let before = ALLOCATIONS.load(Ordering::SeqCst);
    rayon::scope(|_| c.run(20)).unwrap();
    let during = ALLOCATIONS.load(Ordering::SeqCst) - before;
    let touching = (0..4).filter(|&b| c.loads(b).contact_force.norm() > 0.0).count();
    assert_eq!(touching, 4, "every cylinder should be in contact");
    assert_eq!(during, 0, "{during} allocations in 20 warm coupled steps");
}
