//! The tree must not depend on the number of build threads.

use super::{rng, soup};
use crate::raycast::Bvh;
use crate::raycast::bvh::build::MAX_DEPTH;

#[test]
fn build_is_identical_for_any_thread_count() {
    // Large enough for the parallel path of the build.
    let mesh = soup(&mut rng(3), 60_000, 50.0, 0.5);
    let build_with = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("thread pool")
            .install(|| Bvh::build(&mesh))
    };
    let one = build_with(1);
    let four = build_with(4);
    assert!(
        one == four,
        "expected the same tree from 1 and 4 build threads"
    );
    assert!(
        one.depth() <= MAX_DEPTH,
        "expected depth <= {MAX_DEPTH}, got {}",
        one.depth()
    );
    assert_eq!(
        one.triangle_count(),
        60_000,
        "expected every triangle in the tree"
    );
}
