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

/// A trajectory's state at one time.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Sample {
    /// Position (m).
    pub position_m: [f64; 3],
    /// Velocity (m/s): the slope of the segment.
    pub velocity_m_s: [f64; 3],
    /// Closure, 0 to 1.
    pub closure: f64,
}

/// A keyframed trajectory.
#[derive(Debug, Clone, PartialEq)]
pub struct Trajectory {
    times: Vec<f64>,
    positions: Vec<[f64; 3]>,
    closures: Vec<f64>,
}

/// One CSV row, `t_s,x_m,y_m,z_m[,closure]` (also the replay driver's format).
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
pub(crate) struct Row {
    pub t_s: f64,
    pub x_m: f64,
    pub y_m: f64,
    pub z_m: f64,
    #[serde(default)]
    pub closure: f64,
}

/// The longest trajectory accepted (s): a day. Scripted sessions and device replays are
/// minutes long; a keyframe at 10⁹ s is a mistake (wrong units), not a plan.
pub const MAX_DURATION_S: f64 = 86_400.0;

/// The most keyframes a trajectory file may hold: a day of 1 kHz samples would be 86.4 M; a
/// recorded device session of an hour at 1 kHz is 3.6 M.
pub const MAX_KEYFRAMES: usize = 10_000_000;

impl Trajectory {
    /// From keyframes; times must be finite and strictly increasing, spanning at most
    /// [`MAX_DURATION_S`], positions finite, closures in [0, 1].
    pub fn new(keys: Vec<(f64, [f64; 3], f64)>) -> Result<Self, String> {
        if keys.is_empty() {
            return Err("a trajectory needs at least one keyframe".into());
        }
        for (i, (t, p, c)) in keys.iter().enumerate() {
            if !t.is_finite() || !p.iter().all(|x| x.is_finite()) {
                return Err(format!("keyframe {}: time and position must be finite numbers", i + 1));
            }
            if !(0.0..=1.0).contains(c) {
                return Err(format!("keyframe {}: closure {c} is outside [0, 1]", i + 1));
            }
            if i > 0 && *t <= keys[i - 1].0 {
                return Err(format!("keyframe {}: time {t} s does not increase", i + 1));
            }
            if *t - keys[0].0 > MAX_DURATION_S {
                return Err(format!(
                    "keyframe {}: time {t} s is more than {MAX_DURATION_S} s (a day) after the first; times are in seconds",
                    i + 1
                ));
            }
        }
        Ok(Self {
            times: keys.iter().map(|k| k.0).collect(),
            positions: keys.iter().map(|k| k.1).collect(),
            closures: keys.iter().map(|k| k.2).collect(),
        })
    }

    /// Reads a CSV trajectory.
    pub fn read(path: &Path) -> Result<Self, ScriptError> {
        let bad = |message: String| ScriptError::Invalid {
            path: path.display().to_string(),
            message,
        };
        let mut r = csv::ReaderBuilder::new()
            .trim(csv::Trim::All)
            .from_path(path)
            .map_err(|e| bad(e.to_string()))?;
        let mut keys = Vec::new();
        for row in r.deserialize::<Row>() {
            let row = row.map_err(|e| bad(e.to_string()))?;
            if keys.len() == MAX_KEYFRAMES {
                return Err(bad(format!("more than {MAX_KEYFRAMES} keyframes")));
            }
            keys.push((row.t_s, [row.x_m, row.y_m, row.z_m], row.closure));
        }
        Self::new(keys).map_err(bad)
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
        }
    }

    /// Writes the keyframes as CSV (the format [`Trajectory::read`] reads).
    pub fn write(&self, path: &Path) -> std::io::Result<()> {
        let mut w = csv::Writer::from_path(path)?;
        w.write_record(["t_s", "x_m", "y_m", "z_m", "closure"])?;
        for ((t, p), c) in self.times.iter().zip(&self.positions).zip(&self.closures) {
            w.write_record([t, &p[0], &p[1], &p[2], c].map(|x| format!("{x:?}")))?;
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
    fn bad_trajectories_are_refused_with_the_keyframe() {
        assert!(Trajectory::new(vec![]).is_err());
        let e = Trajectory::new(vec![(0.0, [0.0; 3], 0.0), (0.0, [1.0; 3], 0.0)]).unwrap_err();
        assert!(e.contains("keyframe 2"), "{e}");
        let e = Trajectory::new(vec![(0.0, [f64::NAN, 0.0, 0.0], 0.0)]).unwrap_err();
        assert!(e.contains("finite"), "{e}");
        let e = Trajectory::new(vec![(0.0, [0.0; 3], 2.0)]).unwrap_err();
        assert!(e.contains("closure"), "{e}");
        // a keyframe at 10⁹ s (milliseconds or nanoseconds taken for seconds)
        let e = Trajectory::new(vec![(0.0, [0.0; 3], 0.0), (1e9, [0.0; 3], 0.0)]).unwrap_err();
        assert!(e.contains("keyframe 2") && e.contains("a day"), "{e}");
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
}
