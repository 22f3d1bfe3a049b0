//! A strict, linear-time reader for the `.npy` files of a bundle.
//!
//! The NumPy format (`numpy.lib.format`, versions 1.0–3.0): the magic `\x93NUMPY`, two
//! version bytes, the header length (u16 little endian for 1.0, u32 for 2.0 and 3.0), then a
//! header that is the text of a Python dict literal `{'descr': '<f8', 'fortran_order': False,
//! 'shape': (3, 4), }` padded with spaces and ending in a newline, then the data.
//!
//! Everything is checked before a value is decoded: magic, version, the header length
//! against [`MAX_HEADER`] and against the file, the terminating newline, the three keys (no
//! others, none twice), the dtype against the one expected, C order (an array in Fortran order
//! is refused, not read transposed), and that the data is exactly `shape × itemsize` bytes.
//! The header is scanned once, character by character, with no recursion: its cost is linear
//! in its length whatever it holds.

/// Longest header accepted (bytes). NumPy writes 118 bytes or fewer for any 2-D array; a
/// bound keeps a hostile header from costing anything.
pub const MAX_HEADER: usize = 4096;

/// What a header says.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Header {
    /// The dtype string (`<f8`, `<f4`, `<i8`).
    pub descr: String,
    /// The shape.
    pub shape: Vec<u64>,
    /// Where the data starts (bytes from the start of the file).
    pub data_offset: usize,
}

/// Bytes per value of a supported dtype.
pub fn itemsize(descr: &str) -> Option<usize> {
    match descr {
        "<f8" | "<i8" => Some(8),
        "<f4" => Some(4),
        _ => None,
    }
}

/// Parses and checks the header of `bytes` (a whole `.npy` file). The error says what is
/// wrong, for a message naming the file.
pub fn parse_header(bytes: &[u8]) -> Result<Header, String> {
    const MAGIC: &[u8] = b"\x93NUMPY";
    if bytes.len() < 10 || &bytes[..6] != MAGIC {
        return Err("not a .npy file (no \\x93NUMPY magic)".into());
    }
    let (major, minor) = (bytes[6], bytes[7]);
    let (len, start) = match (major, minor) {
        (1, 0) => (u16::from_le_bytes([bytes[8], bytes[9]]) as usize, 10),
        (2, 0) | (3, 0) => {
            if bytes.len() < 12 {
                return Err("truncated header length".into());
            }
            (u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]) as usize, 12)
        }
        _ => return Err(format!(".npy format version {major}.{minor} is not 1.0, 2.0 or 3.0")),
    };
    if len > MAX_HEADER {
        return Err(format!("header of {len} bytes (at most {MAX_HEADER})"));
    }
    let end = start + len;
    if end > bytes.len() {
        return Err(format!(
            "header of {len} bytes runs past the end of the file ({} bytes)",
            bytes.len()
        ));
    }
    let text = std::str::from_utf8(&bytes[start..end]).map_err(|_| "header is not text".to_string())?;
    if major < 3 && !text.is_ascii() {
        return Err("header is not ASCII".into());
    }
    if !text.ends_with('\n') {
        return Err("header does not end with a newline (its length field is wrong)".into());
    }
    let (descr, fortran, shape) = parse_dict(text.trim_end_matches([' ', '\n']))?;
    if fortran {
        return Err("array in Fortran order; save it in C order (numpy.ascontiguousarray)".into());
    }
    Ok(Header {
        descr,
        shape,
        data_offset: end,
    })
}

/// A value of the header dict.
enum Value {
    Str(String),
    Bool(bool),
    Tuple(Vec<u64>),
}

/// Scans `{'descr': '…', 'fortran_order': …, 'shape': (…), }` once, left to right.
fn parse_dict(s: &str) -> Result<(String, bool, Vec<u64>), String> {
    let mut c = Cursor { s: s.as_bytes(), i: 0 };
    c.expect(b'{')?;
    let (mut descr, mut fortran, mut shape) = (None, None, None);
    loop {
        c.skip_ws();
        if c.eat(b'}') {
            break;
        }
        let key = c.string()?;
        c.skip_ws();
        c.expect(b':')?;
        c.skip_ws();
        let value = c.value()?;
        let slot_taken = match (key.as_str(), value) {
            ("descr", Value::Str(v)) => descr.replace(v).is_some(),
            ("fortran_order", Value::Bool(v)) => fortran.replace(v).is_some(),
            ("shape", Value::Tuple(v)) => shape.replace(v).is_some(),
            ("descr" | "fortran_order" | "shape", _) => return Err(format!("header key '{key}' has a value of the wrong type")),
            _ => return Err(format!("unknown header key '{}'", key.chars().take(32).collect::<String>())),
        };
        if slot_taken {
            return Err(format!("header key '{key}' given twice"));
        }
        c.skip_ws();
        if c.eat(b',') {
            continue;
        }
        c.skip_ws();
        c.expect(b'}')?;
        break;
    }
    c.skip_ws();
    if c.i != c.s.len() {
        return Err("text after the header dict".into());
    }
    match (descr, fortran, shape) {
        (Some(d), Some(f), Some(s)) => Ok((d, f, s)),
        _ => Err("header lacks one of 'descr', 'fortran_order', 'shape'".into()),
    }
}

struct Cursor<'a> {
    s: &'a [u8],
    i: usize,
}

impl Cursor<'_> {
    fn skip_ws(&mut self) {
        while self.i < self.s.len() && self.s[self.i] == b' ' {
            self.i += 1;
        }
    }
    fn eat(&mut self, b: u8) -> bool {
        if self.s.get(self.i) == Some(&b) {
            self.i += 1;
            true
        } else {
            false
        }
    }
    fn expect(&mut self, b: u8) -> Result<(), String> {
        if self.eat(b) {
            Ok(())
        } else {
            Err(format!("malformed header: expected '{}' at byte {}", b as char, self.i))
        }
    }
    fn string(&mut self) -> Result<String, String> {
        let q = match self.s.get(self.i) {
            Some(&q @ (b'\'' | b'"')) => q,
            _ => return Err(format!("malformed header: expected a quoted string at byte {}", self.i)),
        };
        self.i += 1;
        let from = self.i;
        while self.i < self.s.len() && self.s[self.i] != q {
            self.i += 1;
        }
        if self.i == self.s.len() {
            return Err("malformed header: unterminated string".into());
        }
        let out = String::from_utf8_lossy(&self.s[from..self.i]).into_owned();
        self.i += 1;
        Ok(out)
    }
    fn value(&mut self) -> Result<Value, String> {
        match self.s.get(self.i) {
            Some(b'\'' | b'"') => Ok(Value::Str(self.string()?)),
            Some(b'(') => {
                self.i += 1;
                let mut dims = Vec::new();
                loop {
                    self.skip_ws();
                    if self.eat(b')') {
                        break;
                    }
                    let from = self.i;
                    while self.i < self.s.len() && self.s[self.i].is_ascii_digit() {
                        self.i += 1;
                    }
                    let digits = std::str::from_utf8(&self.s[from..self.i]).unwrap_or("");
                    let d: u64 = digits
                        .parse()
                        .map_err(|_| format!("malformed header: expected a dimension at byte {from}"))?;
                    dims.push(d);
                    self.skip_ws();
                    if self.eat(b',') {
                        continue;
                    }
                    self.expect(b')')?;
                    break;
                }
                Ok(Value::Tuple(dims))
            }
            _ if self.s[self.i..].starts_with(b"True") => {
                self.i += 4;
                Ok(Value::Bool(true))
            }
            _ if self.s[self.i..].starts_with(b"False") => {
                self.i += 5;
                Ok(Value::Bool(false))
            }
            _ => Err(format!("malformed header: unexpected value at byte {}", self.i)),
        }
    }
}

/// The data length (bytes) of an array of dtype `descr` and `shape`; `None` for an
/// unsupported dtype or a length beyond `u64`.
pub fn data_len(descr: &str, shape: &[u64]) -> Option<u64> {
    shape.iter().try_fold(itemsize(descr)? as u64, |a, &d| a.checked_mul(d))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn file(header: &str, data: &[u8]) -> Vec<u8> {
        let mut b = b"\x93NUMPY\x01\x00".to_vec();
        b.extend((header.len() as u16).to_le_bytes());
        b.extend(header.as_bytes());
        b.extend(data);
        b
    }

    #[test]
    fn reads_what_numpy_writes() {
        let h = "{'descr': '<f8', 'fortran_order': False, 'shape': (2, 3), }          \n";
        let p = parse_header(&file(h, &[0; 48])).unwrap();
        assert_eq!(
            (p.descr.as_str(), p.shape.clone(), p.data_offset),
            ("<f8", vec![2, 3], 10 + h.len())
        );
        assert_eq!(data_len(&p.descr, &p.shape), Some(48));
        let h = "{'descr': '<i8', 'fortran_order': False, 'shape': (5,), }\n";
        assert_eq!(parse_header(&file(h, &[])).unwrap().shape, vec![5]);
        let h = "{'descr': '<f4', 'fortran_order': False, 'shape': (), }\n";
        assert_eq!(parse_header(&file(h, &[])).unwrap().shape, Vec::<u64>::new());
    }

    #[test]
    fn refuses_every_defect_with_a_reason() {
        let ok = "{'descr': '<f8', 'fortran_order': False, 'shape': (2,), }\n";
        let cases = [
            ("{'descr': '<f8', 'fortran_order': True, 'shape': (2,), }\n", "Fortran"),
            ("{'descr': '<f8', 'fortran_order': False, 'shape': (2,), }", "newline"),
            ("{'descr': '<f8', 'fortran_order': False, }\n", "lacks"),
            (
                "{'descr': '<f8', 'descr': '<f8', 'fortran_order': False, 'shape': (2,), }\n",
                "twice",
            ),
            ("{'descr': '<f8', 'fortran_order': False, 'shape': (2,), 'x': 'y'}\n", "unknown"),
            ("{'descr': '<f8', 'fortran_order': False, 'shape': (-2,), }\n", "dimension"),
            ("{'descr': '<f8', 'fortran_order': False, 'shape': ((2,),), }\n", "dimension"),
        ];
        for (h, why) in cases {
            let e = parse_header(&file(h, &[])).unwrap_err();
            assert!(e.contains(why), "{h:?}: {e}");
        }
        // a header length field shifted by one either way
        let mut b = file(ok, &[0; 16]);
        b[8] += 1;
        assert!(parse_header(&b).unwrap_err().contains("newline"));
        b[8] -= 2;
        assert!(parse_header(&b).is_err());
        // magic, version, a length past the end or over the cap
        assert!(parse_header(b"\x93NUMPX\x01\x00\x10\x00").is_err());
        assert!(parse_header(b"\x93NUMPY\x04\x00\x10\x00").unwrap_err().contains("version"));
        assert!(parse_header(b"\x93NUMPY\x01\x00\xff\x00{").unwrap_err().contains("past the end"));
        let mut big = b"\x93NUMPY\x02\x00".to_vec();
        big.extend(100_000u32.to_le_bytes());
        assert!(parse_header(&big).unwrap_err().contains("at most"));
    }

    /// Nested braces and parentheses are refused at the first one that does not belong
    /// (the scan never recurses, so its cost is linear; npyz took over 20 s on 13 braces).
    #[test]
    fn hostile_headers_are_refused() {
        let nested = format!("{}{}\n", "{".repeat(2000), "}".repeat(2000));
        assert!(parse_header(&file(&nested, &[])).unwrap_err().contains("quoted string"));
        let parens = format!("{{'shape': {}\n", "(".repeat(4000));
        assert!(parse_header(&file(&parens, &[])).unwrap_err().contains("dimension"));
    }
}
