//! A small deterministic mutation fuzzer for the readers' tests: byte flips, insertions,
//! deletions, duplicated ranges, truncation, and numbers swapped for boundary values (what
//! breaks parsers: counts that overflow, negative sizes, NaN). Seeded, so a failure names the
//! seed and iteration that reproduce it.
//!
//! Hand-written rather than `cargo fuzz` (needs a nightly toolchain) or proptest (no
//! structure-aware mutation of text formats): it runs in seconds in every CI run.

/// xorshift64*.
pub struct Rng(pub u64);

impl Rng {
    pub fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    pub fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
}

/// Numbers that break parsers.
const BOUNDARY: &[&str] = &[
    "0",
    "-1",
    "1",
    "2147483647",
    "2147483648",
    "4294967295",
    "4294967296",
    "18446744073709551615",
    "18446744073709551616",
    "-9223372036854775809",
    "1e308",
    "1e309",
    "-0",
    "nan",
    "inf",
    "999999999",
    "3",
    "4",
];

/// `input` with 1–4 random mutations.
pub fn mutate(input: &[u8], rng: &mut Rng) -> Vec<u8> {
    let mut b = input.to_vec();
    for _ in 0..1 + rng.below(4) {
        let len = b.len().max(1);
        match rng.below(7) {
            0 => {
                let i = rng.below(len);
                if let Some(x) = b.get_mut(i) {
                    *x ^= 1 << rng.below(8);
                }
            }
            1 => {
                let i = rng.below(len + 1).min(b.len());
                b.insert(i, rng.next() as u8);
            }
            2 => {
                let i = rng.below(len).min(b.len());
                let n = rng.below(16).min(b.len() - i);
                b.drain(i..i + n);
            }
            3 => {
                let i = rng.below(len).min(b.len());
                let n = rng.below(64).min(b.len() - i);
                let chunk = b[i..i + n].to_vec();
                let at = rng.below(b.len() + 1).min(b.len());
                b.splice(at..at, chunk);
            }
            4 => b.truncate(rng.below(len)),
            _ => {
                // replace the k-th number with a boundary value
                let starts: Vec<usize> = (0..b.len())
                    .filter(|&i| b[i].is_ascii_digit() && (i == 0 || !(b[i - 1].is_ascii_digit() || b[i - 1] == b'.')))
                    .collect();
                if let Some(&s) = starts.get(rng.below(starts.len().max(1))) {
                    let mut e = s;
                    while e < b.len() && (b[e].is_ascii_digit() || b[e] == b'.' || b[e] == b'e' || b[e] == b'-') {
                        e += 1;
                    }
                    let v = BOUNDARY[rng.below(BOUNDARY.len())];
                    b.splice(s..e, v.bytes());
                }
            }
        }
    }
    b
}

/// Values that break numerical code, as the little-endian bytes of an `f64` or the low bytes
/// of an integer array's entry.
const BOUNDARY_F64: &[f64] = &[
    f64::NAN,
    f64::INFINITY,
    f64::NEG_INFINITY,
    1e300,
    -1e300,
    1e-300,
    0.0,
    -0.0,
    -1.0,
    9007199254740993.0,
    4294967296.0,
];

/// The `.npy` array `input` with 1–4 of its values, past the header, overwritten by boundary
/// values or random bits — its header and length kept, so the array still parses and what is
/// reached is the code that uses its values.
pub fn poke_npy_values(input: &[u8], rng: &mut Rng) -> Vec<u8> {
    let mut out = input.to_vec();
    // the header ends at the first newline (format 1.0: magic, version, length, dict, '\n')
    let data = input.iter().position(|&b| b == b'\n').map_or(input.len(), |i| i + 1);
    let values = (input.len() - data) / 8;
    if values == 0 {
        return out;
    }
    for _ in 0..1 + rng.below(4) {
        let at = data + 8 * rng.below(values);
        let bytes = match rng.below(3) {
            0 => BOUNDARY_F64[rng.below(BOUNDARY_F64.len())].to_le_bytes(),
            1 => (rng.next() as i64 % 1_000_000 - 500_000).to_le_bytes(),
            _ => rng.next().to_le_bytes(),
        };
        out[at..at + 8].copy_from_slice(&bytes);
    }
    out
}
