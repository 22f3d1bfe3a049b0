//! A tiny deterministic generator (xorshift64, Marsaglia 2003), so that sampled states, test
//! points and benchmark inputs are the same on every run and machine. Not for anything that
//! needs statistical quality or unpredictability.

/// The generator's state (any nonzero seed).
#[derive(Debug, Clone)]
pub struct Rng(pub u64);

impl Rng {
    /// The next 64 bits: `x ^= x << 13; x ^= x >> 7; x ^= x << 17`.
    pub fn next_u64(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }

    /// A number in [0, 1) from the next 53 bits.
    pub fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
}
