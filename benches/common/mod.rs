//! Shared by the criterion benches: the sizes to run.

/// True under `cargo bench` (criterion gets `--bench`); false when `cargo test
/// --all-targets` runs each bench once, unoptimised, as a check that it works.
pub fn benchmarking() -> bool {
    std::env::args().any(|a| a == "--bench")
}

/// `sizes` under `cargo bench`; under `cargo test` only those up to 1e4.
pub fn sizes(sizes: &[usize]) -> Vec<usize> {
    let bench = benchmarking();
    sizes
        .iter()
        .copied()
        .filter(|&n| bench || n <= 10_000)
        .collect()
}
