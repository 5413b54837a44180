//! Criterion benchmark of one fused AA step (one even + one odd sweep) on a periodic 64³ box,
//! reported as node updates per second (criterion's "elements"). `cargo xtask bench` gives the
//! MLUPS table at paper sizes beside the machine's bandwidth ceiling and the lbmpy peer.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use slurry::lattice::Grid;
use slurry::lbm::{Boundaries, Fluid, FluidParams};

fn bench<T: slurry::lbm::Real>(c: &mut Criterion, name: &str) {
    let g = Grid::new(64, 64, 64);
    let mut group = c.benchmark_group(format!("aa_step_{name}"));
    group.throughput(Throughput::Elements(2 * g.nodes() as u64));
    for (label, params) in [("bgk", FluidParams::bgk(0.05)), ("trt", FluidParams::trt(0.05))] {
        let mut f = Fluid::<T>::new(g, params, Boundaries::periodic()).expect("valid set-up");
        f.initialize(|x, _, _| (1.0, [0.01 * (x as f64 * 0.1).sin(), 0.0, 0.0]));
        group.bench_function(BenchmarkId::from_parameter(label), |b| {
            b.iter(|| {
                f.step();
                f.step();
            })
        });
    }
    group.finish();
}

fn kernels(c: &mut Criterion) {
    bench::<f32>(c, "f32");
    bench::<f64>(c, "f64");
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(10);
    targets = kernels
}
criterion_main!(benches);
