//! Finds the line of a key path in TOML source, so validation errors can say where.

use toml::de::{DeTable, DeValue};

/// One step of a key path: a table key or an array index.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Seg<'a> {
    /// A key of a table.
    Key(&'a str),
    /// An index into an array (0-based).
    Index(usize),
}

/// 1-based line number of byte `offset` in `text`.
pub fn line_of_offset(text: &str, offset: usize) -> usize {
    text.as_bytes()[..offset.min(text.len())].iter().filter(|&&b| b == b'\n').count() + 1
}

/// `organs[0].materials[1].poisson` for a path.
pub fn dotted(path: &[Seg<'_>]) -> String {
    let mut s = String::new();
    for seg in path {
        match seg {
            Seg::Key(k) => {
                if !s.is_empty() {
                    s.push('.');
                }
                s.push_str(k);
            }
            Seg::Index(i) => s.push_str(&format!("[{i}]")),
        }
    }
    s
}

/// The line of the deepest element of `path` present in `text` (the key itself when found).
pub fn line_of_path(text: &str, path: &[Seg<'_>]) -> Option<usize> {
    let root = DeTable::parse(text).ok()?;
    let mut table: &DeTable<'_> = root.get_ref();
    let mut value: Option<&DeValue<'_>> = None;
    let mut line = None;
    for seg in path {
        match (seg, value) {
            (Seg::Key(k), None) | (Seg::Key(k), Some(DeValue::Table(_))) => {
                if let Some(DeValue::Table(t)) = value {
                    table = t;
                }
                let Some((key, v)) = table.iter().find(|(key, _)| key.get_ref().as_ref() == *k) else {
                    break;
                };
                line = Some(line_of_offset(text, key.span().start));
                value = Some(v.get_ref());
            }
            (Seg::Index(i), Some(DeValue::Array(a))) => {
                let Some(item) = a.get(*i) else { break };
                if item.span().start > 0 || line.is_none() {
                    line = Some(line_of_offset(text, item.span().start));
                }
                value = Some(item.get_ref());
            }
            _ => break,
        }
    }
    line
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_nested_keys_in_arrays_of_tables() {
        let text = "[scene]\nname = \"x\"\n\n[[organs]]\nname = \"a\"\n\n[[organs]]\nname = \"b\"\ndensity = 3\n";
        assert_eq!(line_of_path(text, &[Seg::Key("scene"), Seg::Key("name")]), Some(2));
        assert_eq!(
            line_of_path(text, &[Seg::Key("organs"), Seg::Index(1), Seg::Key("density")]),
            Some(9)
        );
        assert_eq!(
            dotted(&[Seg::Key("organs"), Seg::Index(1), Seg::Key("density")]),
            "organs[1].density"
        );
    }
}
