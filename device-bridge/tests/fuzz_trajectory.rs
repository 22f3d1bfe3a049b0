//! Mutation fuzzing of the CSV trajectory reader (scripted sessions, device replays): every
//! mutant of `tests/corpus/trajectory.csv` is read into a trajectory or refused with an
//! error — never a panic — and every trajectory accepted is bounded and finite.

use std::panic::{AssertUnwindSafe, catch_unwind};

use vademecum_bridge::trajectory::{MAX_DURATION_S, Trajectory};

struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
}

const BOUNDARY: &[&str] = &["0", "-1", "1e9", "1e308", "nan", "inf", "-inf", "86400.5", "2", ""];

#[test]
fn trajectory_reading_never_panics_and_accepts_only_bounded_paths() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("t.csv");
    let good = std::fs::read(std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/corpus/trajectory.csv")).unwrap();
    let mut rng = Rng(7);
    let mut accepted = 0;
    for i in 0..3000 {
        let mut b = good.clone();
        for _ in 0..1 + rng.below(3) {
            match rng.below(4) {
                0 if !b.is_empty() => {
                    let at = rng.below(b.len());
                    b[at] ^= 1 << rng.below(8);
                }
                1 => {
                    // replace one field with a boundary value
                    let text = String::from_utf8_lossy(&b).into_owned();
                    let parts: Vec<&str> = text.split_inclusive([',', '\n']).collect();
                    let k = rng.below(parts.len());
                    let v = BOUNDARY[rng.below(BOUNDARY.len())];
                    let mut out = String::new();
                    for (j, part) in parts.iter().enumerate() {
                        if j == k {
                            out.push_str(v);
                            out.extend(part.chars().last().filter(|c| *c == ',' || *c == '\n'));
                        } else {
                            out.push_str(part);
                        }
                    }
                    b = out.into_bytes();
                }
                2 => b.truncate(rng.below(b.len().max(1))),
                _ => {
                    let at = rng.below(b.len() + 1).min(b.len());
                    b.insert(at, [b',', b'\n', b'-', b'9', b'e'][rng.below(5)]);
                }
            }
        }
        std::fs::write(&path, &b).unwrap();
        match catch_unwind(AssertUnwindSafe(|| Trajectory::read(&path))) {
            Ok(Ok(t)) => {
                accepted += 1;
                assert!(t.duration_s() <= MAX_DURATION_S && t.duration_s().is_finite(), "mutant {i}");
                let s = t.at(0.5 * t.duration_s());
                assert!(s.position_m.iter().all(|x| x.is_finite()), "mutant {i}");
            }
            Ok(Err(_)) => {}
            Err(_) => panic!("mutant {i} panicked: {:?}", String::from_utf8_lossy(&b)),
        }
    }
    eprintln!("{accepted} of 3000 mutants accepted");
    assert!(accepted > 0);
}
