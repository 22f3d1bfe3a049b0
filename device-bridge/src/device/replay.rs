//! Replay of recorded device samples.
//!
//! The file is CSV with a header, `t_s,x_m,y_m,z_m[,closure]`, one row per recorded sample,
//! times non-decreasing. At tick time `t` the replay returns the last sample recorded at or
//! before `t` (sample and hold, no interpolation), exactly as recorded: a recording with
//! dropouts (`NaN`), glitches (jumps) or excursions outside the workspace reaches the input
//! guard unchanged, which is what a replay is for.

use std::path::Path;

use super::{Device, DeviceError, DeviceReading};
use crate::trajectory::Row;

/// Recorded samples played back (see the [module docs](self)).
#[derive(Debug, Clone)]
pub struct Replay {
    rows: Vec<Row>,
    cursor: usize,
}

impl Replay {
    /// Reads a recording; times must be finite and non-decreasing (positions may be
    /// anything, even `NaN`).
    pub fn read(path: &Path) -> Result<Self, DeviceError> {
        let bad = |m: String| DeviceError::Open(format!("{}: {m}", path.display()));
        let bytes = vademecum_files::read_regular(path, crate::trajectory::MAX_SCRIPT_BYTES).map_err(|e| bad(e.to_string()))?;
        let mut r = csv::ReaderBuilder::new().trim(csv::Trim::All).from_reader(bytes.as_slice());
        let mut rows: Vec<Row> = Vec::new();
        for row in r.deserialize::<Row>() {
            let row = row.map_err(|e| bad(e.to_string()))?;
            if !row.t_s.is_finite() || rows.last().is_some_and(|l| row.t_s < l.t_s) {
                return Err(bad(format!(
                    "row {}: time {} s is not finite or goes backwards",
                    rows.len() + 1,
                    row.t_s
                )));
            }
            rows.push(row);
        }
        if rows.is_empty() {
            return Err(bad("the recording has no sample".into()));
        }
        let t0 = rows[0].t_s;
        for r in &mut rows {
            r.t_s -= t0;
        }
        Ok(Self { rows, cursor: 0 })
    }

    /// Number of recorded samples.
    pub fn len(&self) -> usize {
        self.rows.len()
    }

    /// Whether there is no sample (never true for a replay that was read).
    pub fn is_empty(&self) -> bool {
        self.rows.is_empty()
    }
}

impl Device for Replay {
    fn name(&self) -> &str {
        "replay"
    }

    fn read(&mut self, t_s: f64) -> Result<DeviceReading, DeviceError> {
        while self.cursor + 1 < self.rows.len() && self.rows[self.cursor + 1].t_s <= t_s {
            self.cursor += 1;
        }
        let r = self.rows[self.cursor];
        Ok(DeviceReading {
            position_m: [r.x_m, r.y_m, r.z_m],
            velocity_m_s: [0.0; 3],
            closure: r.closure,
            ..DeviceReading::default()
        })
    }

    fn write_force(&mut self, _force_n: [f64; 3]) {}

    fn finished(&self, t_s: f64) -> bool {
        t_s > self.rows[self.rows.len() - 1].t_s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn samples_are_held_until_the_next_one_bad_values_included() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("rec.csv");
        std::fs::write(&p, "t_s,x_m,y_m,z_m\n10.0,0,0,0\n10.002,NaN,0,0\n10.004,0.5,0,0\n").unwrap();
        let mut r = Replay::read(&p).unwrap();
        assert_eq!(r.read(0.001).unwrap().position_m, [0.0; 3]);
        assert!(r.read(0.0025).unwrap().position_m[0].is_nan());
        assert_eq!(r.read(0.01).unwrap().position_m[0], 0.5);
        assert!(r.finished(0.01) && !r.finished(0.003));
    }

    #[test]
    fn a_recording_going_back_in_time_is_refused_with_its_row() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("rec.csv");
        std::fs::write(&p, "t_s,x_m,y_m,z_m\n1,0,0,0\n0.5,0,0,0\n").unwrap();
        let e = Replay::read(&p).unwrap_err().to_string();
        assert!(e.contains("rec.csv") && e.contains("row 2"), "{e}");
    }
}
