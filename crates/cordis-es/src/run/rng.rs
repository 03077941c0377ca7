//! Random streams that make a run depend on its seed only, whatever the thread count.
//!
//! Every random draw comes from a stream named by `(seed, generation, stream)`: the strategy's
//! sequential operators use stream 0 of their generation, and work done for individual k in
//! parallel uses stream `k + 1`. No generator state crosses a generation, so a checkpoint needs
//! no RNG state to resume exactly.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

pub type Rng = ChaCha8Rng;

/// SplitMix64 finaliser: spreads nearby integers over the whole 64-bit range.
fn mix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// The generator of stream `stream` at generation `generation` of a run seeded with `seed`.
pub fn stream(seed: u64, generation: u64, stream: u64) -> Rng {
    let mut rng = ChaCha8Rng::seed_from_u64(mix(seed ^ mix(generation)));
    rng.set_stream(stream);
    rng
}

/// A standard normal draw.
pub fn normal(rng: &mut Rng) -> f64 {
    use rand_distr::Distribution;
    rand_distr::StandardNormal.sample(rng)
}

/// A uniform draw in [0, 1).
pub fn uniform(rng: &mut Rng) -> f64 {
    use rand::Rng as _;
    rng.random::<f64>()
}

/// A uniform index in 0..n (n > 0).
pub fn index(rng: &mut Rng, n: usize) -> usize {
    use rand::Rng as _;
    rng.random_range(0..n)
}

/// A rank drawn with probability decreasing linearly from the best (0) to the worst (n-1):
/// the thesis' "tirage biaisé en faveur des plus performants".
pub fn biased_rank(rng: &mut Rng, n: usize) -> usize {
    let u = uniform(rng);
    ((n as f64) * (1.0 - (1.0 - u).sqrt()))
        .floor()
        .min((n - 1) as f64) as usize
}
