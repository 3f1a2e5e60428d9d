//! Criterion benchmarks of the core kernels. Run: `cargo bench -p heapgrasp-benches`.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use heapgrasp_benches::{camera, grid, ring, sphere_masks};
use heapgrasp_core::OccupancyGrid;

fn carve(c: &mut Criterion) {
    let mut group = c.benchmark_group("carve_30_views");
    group.sample_size(20);
    for (w, h) in [(320, 240), (640, 480)] {
        let cam = camera(w, h);
        let poses = ring(30);
        let masks = sphere_masks(&cam, &poses);
        for r in [40usize, 80, 160] {
            let spec = grid(r);
            group.throughput(Throughput::Elements(
                (spec.voxel_count() * poses.len()) as u64,
            ));
            group.bench_with_input(BenchmarkId::new(format!("{w}x{h}"), r), &r, |b, _| {
                let mut occ = OccupancyGrid::new(spec);
                b.iter(|| {
                    occ.reset();
                    occ.integrate_many(&cam, &poses, &masks)
                        .expect("valid input");
                });
            });
        }
    }
    group.finish();
}

criterion_group!(benches, carve);
criterion_main!(benches);
