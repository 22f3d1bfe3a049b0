//! Keyframed trajectories: `(t, position, closure)` read from CSV and linearly interpolated —
//! the scripted hand of the simulated stylus, and the tool path of the server's headless runs.
//!
//! CSV format (header required, SI units, times increasing, at most [`MAX_DURATION_S`] from
//! the first keyframe to the last):
//!
//! ```text
//! t_s,x_m,y_m,z_m[,closure]
//! 0.0,0.0,0.0,0.05
//! 1.0,0.0,0.0,0.03
//! ```
//!
//! A scalpel's trajectory adds its blade on every row: the other end of the cutting edge
//! (`bx_m,by_m,bz_m`; `x_m,y_m,z_m` is the tip) and the orientation as a unit quaternion
//! (`qw,qx,qy,qz`; the tool frame's y axis turned by it is the normal of the blade's plane).
//! The end is interpolated linearly, the orientation by normalised linear interpolation.
//!
//! ```text
//! t_s,x_m,y_m,z_m,closure,bx_m,by_m,bz_m,qw,qx,qy,qz
//! 0.0,4.0,-0.1,5.1,0,4.0,1.1,5.1,0.7071,0,0,-0.7071
//! ```

use std::path::Path;

use serde::Deserialize;

/// Why a trajectory could not be read.
#[derive(Debug, thiserror::Error)]
pub enum ScriptError {
    /// The file could not be read or parsed.
    #[error("{path}: {message}")]
    Invalid {
        /// The file.
        path: String,
        /// What is wrong, with the line where known.
        message: String,
    },
}

/// Why keyframes do not make a trajectory ([`Trajectory::new`], [`Trajectory::with_blades`]);
/// keyframes are numbered from 1.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum KeyframeError {
    /// No keyframe at all.
    #[error("a trajectory needs at least one keyframe")]
    Empty,
    /// A time or a position that is not a finite number.
    #[error("keyframe {0}: time and position must be finite numbers")]
    NotFinite(usize),
    /// A closure outside [0, 1].
    #[error("keyframe {keyframe}: closure {closure} is outside [0, 1]")]
    Closure {
        /// The keyframe.
        keyframe: usize,
        /// Its closure.
        closure: f64,
    },
    /// A time not after the keyframe before.
    #[error("keyframe {keyframe}: time {t_s} s does not increase")]
    NotIncreasing {
        /// The keyframe.
        keyframe: usize,
        /// Its time (s).
        t_s: f64,
    },
    /// A time more than [`MAX_DURATION_S`] after the first (milliseconds taken for seconds).
    #[error("keyframe {keyframe}: time {t_s} s is more than {MAX_DURATION_S} s (a day) after the first; times are in seconds")]
    TooLate {
        /// The keyframe.
        keyframe: usize,
        /// Its time (s).
        t_s: f64,
    },
    /// Not one blade per keyframe.
    #[error("{blades} blades for {keyframes} keyframes")]
    BladeCount {
        /// Blades given.
        blades: usize,
        /// Keyframes.
        keyframes: usize,
    },
    /// A blade whose end is not finite or whose orientation is not a unit quaternion.
    #[error("keyframe {0}: the blade's end must be finite and its orientation a unit quaternion")]
    Blade(usize),
}

/// A trajectory's state at one time.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Sample {
    /// Position (m).
    pub position_m: [f64; 3],
    /// Velocity (m/s): the slope of the segment.
    pub velocity_m_s: [f64; 3],
    /// Closure, 0 to 1.
    pub closure: f64,
    /// A scalpel's blade, when the trajectory has one.
    pub blade: Option<BladeKey>,
}

/// A scalpel's blade at a keyframe: the other end of its edge and its orientation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BladeKey {
    /// The other end of the cutting edge (m); the trajectory's position is the tip.
    pub end_m: [f64; 3],
    /// Unit quaternion `[w, x, y, z]`.
    pub orientation: [f64; 4],
}

/// A keyframed trajectory.
#[derive(Debug, Clone, PartialEq)]
pub struct Trajectory {
    times: Vec<f64>,
    positions: Vec<[f64; 3]>,
    closures: Vec<f64>,
    blades: Option<Vec<BladeKey>>,
}

/// One CSV row, `t_s,x_m,y_m,z_m[,closure][,bx_m,by_m,bz_m,qw,qx,qy,qz]` (also the replay
/// driver's format, which ignores the blade).
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
pub(crate) struct Row {
    pub t_s: f64,
    pub x_m: f64,
    pub y_m: f64,
    pub z_m: f64,
    #[serde(default)]
    pub closure: f64,
    #[serde(default)]
    pub bx_m: Option<f64>,
    #[serde(default)]
    pub by_m: Option<f64>,
    #[serde(default)]
    pub bz_m: Option<f64>,
    #[serde(default)]
    pub qw: Option<f64>,
    #[serde(default)]
    pub qx: Option<f64>,
    #[serde(default)]
    pub qy: Option<f64>,
    #[serde(default)]
    pub qz: Option<f64>,
}

impl Row {
    /// The row's blade: `Ok(None)` without blade columns, an error if only some are set.
    fn blade(&self) -> Result<Option<BladeKey>, String> {
        let b = [self.bx_m, self.by_m, self.bz_m, self.qw, self.qx, self.qy, self.qz];
        match b.iter().filter(|v| v.is_some()).count() {
            0 => Ok(None),
            7 => {
                let v = b.map(|v| v.unwrap_or_default());
                Ok(Some(BladeKey {
                    end_m: [v[0], v[1], v[2]],
                    orientation: [v[3], v[4], v[5], v[6]],
                }))
            }
            _ => Err("a blade needs all of bx_m, by_m, bz_m, qw, qx, qy, qz".into()),
        }
    }
}

/// The longest trajectory accepted (s): a day. Scripted sessions and device replays are
/// minutes long; a keyframe at 10⁹ s is a mistake (wrong units), not a plan.
pub const MAX_DURATION_S: f64 = 86_400.0;

/// The most keyframes a trajectory file may hold: a day of 1 kHz samples would be 86.4 M; a
/// recorded device session of an hour at 1 kHz is 3.6 M.
pub const MAX_KEYFRAMES: usize = 10_000_000;

/// Most bytes of a trajectory or recording file: an hour of a 1 kHz recording (3.6 million
/// rows) or a million rows of a scalpel's thirteen columns at full precision fit well within
/// it; the file is read whole before it is parsed.
pub const MAX_SCRIPT_BYTES: u64 = 1 << 30;

impl Trajectory {
    /// From keyframes; times must be finite and strictly increasing, spanning at most
    /// [`MAX_DURATION_S`], positions finite, closures in [0, 1].
    pub fn new(keys: Vec<(f64, [f64; 3], f64)>) -> Result<Self, KeyframeError> {
        if keys.is_empty() {
            return Err(KeyframeError::Empty);
        }
        for (i, &(t_s, p, closure)) in keys.iter().enumerate() {
            let keyframe = i + 1;
            if !t_s.is_finite() || !p.iter().all(|x| x.is_finite()) {
                return Err(KeyframeError::NotFinite(keyframe));
            }
            if !(0.0..=1.0).contains(&closure) {
                return Err(KeyframeError::Closure { keyframe, closure });
            }
            if i > 0 && t_s <= keys[i - 1].0 {
                return Err(KeyframeError::NotIncreasing { keyframe, t_s });
            }
            if t_s - keys[0].0 > MAX_DURATION_S {
                return Err(KeyframeError::TooLate { keyframe, t_s });
            }
        }
        Ok(Self {
            times: keys.iter().map(|k| k.0).collect(),
            positions: keys.iter().map(|k| k.1).collect(),
            closures: keys.iter().map(|k| k.2).collect(),
            blades: None,
        })
    }

    /// The trajectory of a scalpel: one blade per keyframe, each with a finite end and a
    /// finite orientation of norm within 0.1 of 1.
    pub fn with_blades(mut self, blades: Vec<BladeKey>) -> Result<Self, KeyframeError> {
        if blades.len() != self.times.len() {
            return Err(KeyframeError::BladeCount {
                blades: blades.len(),
                keyframes: self.times.len(),
            });
        }
        for (i, b) in blades.iter().enumerate() {
            let q = b.orientation.iter().map(|x| x * x).sum::<f64>().sqrt();
            if !b.end_m.iter().chain(&b.orientation).all(|x| x.is_finite()) || (q - 1.0).abs() > 0.1 {
                return Err(KeyframeError::Blade(i + 1));
            }
        }
        self.blades = Some(blades);
        Ok(self)
    }

    /// Whether the trajectory carries a scalpel's blade.
    pub fn has_blade(&self) -> bool {
        self.blades.is_some()
    }

    /// The keyframe with the longest blade edge (tip to other end): its time (s) and the
    /// length (m); `None` without a blade.
    pub fn longest_blade(&self) -> Option<(f64, f64)> {
        let blades = self.blades.as_ref()?;
        self.times
            .iter()
            .zip(&self.positions)
            .zip(blades)
            .map(|((&t, p), b)| (t, (0..3).map(|k| (b.end_m[k] - p[k]).powi(2)).sum::<f64>().sqrt()))
            .max_by(|a, b| a.1.total_cmp(&b.1))
    }

    /// Reads a CSV trajectory.
    pub fn read(path: &Path) -> Result<Self, ScriptError> {
        let bad = |message: String| ScriptError::Invalid {
            path: path.display().to_string(),
            message,
        };
        // a regular file only, bounded: a FIFO would block the read, /dev/zero never end it
        let bytes = vademecum_files::read_regular(path, MAX_SCRIPT_BYTES).map_err(|e| bad(e.to_string()))?;
        let mut r = csv::ReaderBuilder::new().trim(csv::Trim::All).from_reader(bytes.as_slice());
        let mut keys = Vec::new();
        let mut blades = Vec::new();
        for row in r.deserialize::<Row>() {
            let row = row.map_err(|e| bad(e.to_string()))?;
            if keys.len() == MAX_KEYFRAMES {
                return Err(bad(format!("more than {MAX_KEYFRAMES} keyframes")));
            }
            let blade = row.blade().map_err(|e| bad(format!("keyframe {}: {e}", keys.len() + 1)))?;
            if blade.is_some() != (blades.len() == keys.len()) && !keys.is_empty() {
                return Err(bad(format!(
                    "keyframe {}: either every row has a blade or none does",
                    keys.len() + 1
                )));
            }
            blades.extend(blade);
            keys.push((row.t_s, [row.x_m, row.y_m, row.z_m], row.closure));
        }
        let t = Self::new(keys).map_err(|e| bad(e.to_string()))?;
        if blades.is_empty() {
            Ok(t)
        } else {
            t.with_blades(blades).map_err(|e| bad(e.to_string()))
        }
    }

    /// Duration (s) from the first keyframe to the last.
    pub fn duration_s(&self) -> f64 {
        self.times[self.times.len() - 1] - self.times[0]
    }

    /// The keyframes' bounding box (m): lower and upper corner.
    pub fn bounds(&self) -> ([f64; 3], [f64; 3]) {
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for p in &self.positions {
            for k in 0..3 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        (lo, hi)
    }

    /// The state at `t` seconds after the first keyframe (held, at rest, at the ends).
    pub fn at(&self, t: f64) -> Sample {
        let t = t + self.times[0];
        let i = self.times.partition_point(|&x| x <= t);
        let blade = self.blades.as_ref().map(|b| {
            if i == 0 || i >= self.times.len() {
                b[i.clamp(1, self.times.len()) - 1]
            } else {
                let a = (t - self.times[i - 1]) / (self.times[i] - self.times[i - 1]);
                let (k0, k1) = (b[i - 1], b[i]);
                // the shorter way round: q and −q are the same rotation
                let dot: f64 = (0..4).map(|k| k0.orientation[k] * k1.orientation[k]).sum();
                let s = if dot < 0.0 { -1.0 } else { 1.0 };
                let q: [f64; 4] = std::array::from_fn(|k| k0.orientation[k] + a * (s * k1.orientation[k] - k0.orientation[k]));
                let n = q.iter().map(|x| x * x).sum::<f64>().sqrt();
                BladeKey {
                    end_m: std::array::from_fn(|k| k0.end_m[k] + a * (k1.end_m[k] - k0.end_m[k])),
                    orientation: if n > 0.0 { q.map(|x| x / n) } else { k0.orientation },
                }
            }
        });
        let (position_m, closure, velocity_m_s) = if i == 0 {
            (self.positions[0], self.closures[0], [0.0; 3])
        } else if i >= self.times.len() {
            (self.positions[i - 1], self.closures[i - 1], [0.0; 3])
        } else {
            let (t0, t1) = (self.times[i - 1], self.times[i]);
            let a = (t - t0) / (t1 - t0);
            let (p0, p1) = (self.positions[i - 1], self.positions[i]);
            let lerp = |k: usize| p0[k] + a * (p1[k] - p0[k]);
            let vel = |k: usize| (p1[k] - p0[k]) / (t1 - t0);
            (
                [lerp(0), lerp(1), lerp(2)],
                self.closures[i - 1] + a * (self.closures[i] - self.closures[i - 1]),
                [vel(0), vel(1), vel(2)],
            )
        };
        Sample {
            position_m,
            velocity_m_s,
            closure,
            blade,
        }
    }

    /// Writes the keyframes as CSV (the format [`Trajectory::read`] reads).
    pub fn write(&self, path: &Path) -> std::io::Result<()> {
        let mut w = csv::Writer::from_path(path)?;
        let mut header = vec!["t_s", "x_m", "y_m", "z_m", "closure"];
        if self.blades.is_some() {
            header.extend(["bx_m", "by_m", "bz_m", "qw", "qx", "qy", "qz"]);
        }
        w.write_record(&header)?;
        for (k, ((t, p), c)) in self.times.iter().zip(&self.positions).zip(&self.closures).enumerate() {
            let mut row: Vec<f64> = vec![*t, p[0], p[1], p[2], *c];
            if let Some(b) = &self.blades {
                row.extend(b[k].end_m.iter().chain(&b[k].orientation));
            }
            w.write_record(row.iter().map(|x| format!("{x:?}")))?;
        }
        w.flush()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn interpolates_between_keyframes_and_holds_at_the_ends() {
        let tr = Trajectory::new(vec![(1.0, [0.0, 0.0, 0.0], 0.0), (3.0, [2.0, 0.0, -2.0], 1.0)]).unwrap();
        assert_eq!(tr.duration_s(), 2.0);
        let m = tr.at(1.0);
        assert_eq!(m.position_m, [1.0, 0.0, -1.0]);
        assert_eq!(m.velocity_m_s, [1.0, 0.0, -1.0]);
        assert!((m.closure - 0.5).abs() < 1e-12);
        assert_eq!(tr.at(-5.0).position_m, [0.0; 3]);
        assert_eq!(tr.at(50.0).position_m, [2.0, 0.0, -2.0]);
    }

    #[test]
    fn a_scalpel_trajectory_interpolates_its_blade_and_round_trips_through_csv() {
        let h = std::f64::consts::FRAC_1_SQRT_2;
        let tr = Trajectory::new(vec![(0.0, [0.0; 3], 0.0), (2.0, [2.0, 0.0, 0.0], 0.0)])
            .unwrap()
            .with_blades(vec![
                BladeKey {
                    end_m: [0.0, 0.0, 1.0],
                    orientation: [1.0, 0.0, 0.0, 0.0],
                },
                BladeKey {
                    end_m: [2.0, 0.0, 3.0],
                    orientation: [-h, 0.0, 0.0, -h],
                },
            ])
            .unwrap();
        let b = tr.at(1.0).blade.unwrap();
        assert_eq!(b.end_m, [1.0, 0.0, 2.0]);
        // half way to a quarter turn about z (given as −q: the shorter way round)
        let e = (std::f64::consts::PI / 8.0).cos();
        assert!((b.orientation[0] - e).abs() < 0.01 && b.orientation[3] > 0.3, "{b:?}");
        assert_eq!(tr.at(9.0).blade.unwrap().end_m, [2.0, 0.0, 3.0]);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("t.csv");
        tr.write(&path).unwrap();
        assert_eq!(Trajectory::read(&path).unwrap(), tr);
        // a row without its blade
        std::fs::write(
            &path,
            "t_s,x_m,y_m,z_m,closure,bx_m,by_m,bz_m,qw,qx,qy,qz\n0,0,0,0,0,0,0,1,1,0,0,0\n1,0,0,0,0,,,,,,,\n",
        )
        .unwrap();
        let e = Trajectory::read(&path).unwrap_err().to_string();
        assert!(e.contains("keyframe 2"), "{e}");
        std::fs::write(
            &path,
            "t_s,x_m,y_m,z_m,closure,bx_m,by_m,bz_m,qw,qx,qy,qz\n0,0,0,0,0,0,0,1,0,0,0,0\n",
        )
        .unwrap();
        let e = Trajectory::read(&path).unwrap_err().to_string();
        assert!(e.contains("unit quaternion"), "{e}");
    }

    #[test]
    fn bad_trajectories_are_refused_with_the_keyframe() {
        assert!(Trajectory::new(vec![]).is_err());
        let e = Trajectory::new(vec![(0.0, [0.0; 3], 0.0), (0.0, [1.0; 3], 0.0)]).unwrap_err();
        assert!(matches!(e, KeyframeError::NotIncreasing { keyframe: 2, .. }), "{e}");
        assert!(e.to_string().contains("keyframe 2"), "{e}");
        let e = Trajectory::new(vec![(0.0, [f64::NAN, 0.0, 0.0], 0.0)]).unwrap_err();
        assert_eq!(e, KeyframeError::NotFinite(1));
        assert!(e.to_string().contains("finite"), "{e}");
        let e = Trajectory::new(vec![(0.0, [0.0; 3], 2.0)]).unwrap_err();
        assert!(e.to_string().contains("closure"), "{e}");
        // a keyframe at 10⁹ s (milliseconds or nanoseconds taken for seconds)
        let e = Trajectory::new(vec![(0.0, [0.0; 3], 0.0), (1e9, [0.0; 3], 0.0)]).unwrap_err();
        assert!(e.to_string().contains("keyframe 2") && e.to_string().contains("a day"), "{e}");
        assert!(Trajectory::new(vec![(5.0, [0.0; 3], 0.0), (5.0 + MAX_DURATION_S, [0.0; 3], 0.0)]).is_ok());
    }

    #[test]
    fn csv_round_trips_and_reports_bad_rows() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("t.csv");
        let tr = Trajectory::new(vec![(0.0, [0.1, 0.2, 0.3], 0.0), (0.5, [0.1, 0.2, 0.25], 0.25)]).unwrap();
        tr.write(&p).unwrap();
        assert_eq!(Trajectory::read(&p).unwrap(), tr);
        std::fs::write(&p, "t_s,x_m,y_m,z_m\n0,0,0,0\n1,0,zero,0\n").unwrap();
        let e = Trajectory::read(&p).unwrap_err().to_string();
        assert!(e.contains("t.csv") && e.contains("line: 3"), "{e}");
    }

    #[test]
    fn special_files_are_refused_as_trajectories_and_recordings() {
        use crate::device::replay::Replay;
        let dir = tempfile::tempdir().unwrap();
        let fifo = dir.path().join("pipe");
        assert!(std::process::Command::new("mkfifo").arg(&fifo).status().unwrap().success());
        let zero = dir.path().join("zero.csv");
        std::os::unix::fs::symlink("/dev/zero", &zero).unwrap();
        // read on threads: a reader that blocks on the FIFO fails the test instead of hanging it
        for (p, what) in [(fifo, "FIFO"), (zero, "device")] {
            let (tx, rx) = std::sync::mpsc::channel();
            std::thread::spawn(move || {
                let a = Trajectory::read(&p).unwrap_err().to_string();
                let b = Replay::read(&p).err().map(|e| e.to_string()).unwrap_or_default();
                let _ = tx.send((a, b));
            });
            let (a, b) = rx
                .recv_timeout(std::time::Duration::from_secs(10))
                .expect("the read does not block");
            for e in [a, b] {
                assert!(e.contains(what) && e.contains("not a regular file"), "{e}");
            }
        }
    }
}
