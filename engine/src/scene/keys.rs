//! Setting keys of a scene's text by path: a variant of a scene (a built-in at another mesh
//! size, a tool swapped) made without editing its text by hand, where a key that is not
//! where the path says is an error, not an edit that silently does nothing.
//!
//! A path is dotted from the root, with array indices: `organs[0].mesh.divisions`,
//! `fidelity.tearing.grasp_sites`, `tools[0].max_force`; `tools[0]` replaces the whole
//! element. Every table on the way must exist (an edit never invents the structure it
//! assumes); the last key may be new. Values are TOML (`[8, 8, 8]`, `"fem"`, `0.5`,
//! `{ kind = "probe", radius = 2.0 }`). Comments and layout are not kept.

use toml::{Table, Value};

/// Why a key could not be set.
#[derive(Debug, thiserror::Error)]
pub enum KeyError {
    /// The scene's text is not TOML.
    #[error("the scene is not TOML: {0}")]
    Scene(#[source] Box<toml::de::Error>),
    /// A value is not TOML.
    #[error("`{path}`: the value `{value}` is not TOML: {source}")]
    Value {
        /// The key.
        path: String,
        /// The value's text.
        value: String,
        /// Why not.
        source: Box<toml::de::Error>,
    },
    /// The path does not lead where it says (a missing table, an index past the end, a key
    /// that is no table), or is not a path.
    #[error("`{path}`: {why}")]
    Path {
        /// The key.
        path: String,
        /// What is missing.
        why: String,
    },
}

/// The scene `text` with each `(path, value)` of `edits` set, in order (module docs).
pub fn with_keys(text: &str, edits: &[(&str, &str)]) -> Result<String, KeyError> {
    let mut root: Table = toml::from_str(text).map_err(|e| KeyError::Scene(Box::new(e)))?;
    for &(path, value) in edits {
        let parsed = parse_value(path, value)?;
        set(&mut root, path, parsed)?;
    }
    Ok(toml::to_string(&root).expect("a TOML table serialises"))
}

/// A TOML value from its text (an inline value: a number, string, array or inline table).
fn parse_value(path: &str, value: &str) -> Result<Value, KeyError> {
    let mut wrapped: Table = toml::from_str(&format!("v = {value}")).map_err(|source| KeyError::Value {
        path: path.to_string(),
        value: value.to_string(),
        source: Box::new(source),
    })?;
    Ok(wrapped.remove("v").expect("the key just parsed"))
}

/// A segment of a path: a key, with an index when it names an array's element.
fn segment<'a>(path: &str, seg: &'a str) -> Result<(&'a str, Option<usize>), KeyError> {
    let bad = |why: String| KeyError::Path {
        path: path.to_string(),
        why,
    };
    match seg.split_once('[') {
        None => Ok((seg, None)),
        Some((name, rest)) => {
            let index = rest
                .strip_suffix(']')
                .and_then(|i| i.parse::<usize>().ok())
                .ok_or_else(|| bad(format!("`{seg}` is not `name[index]`")))?;
            Ok((name, Some(index)))
        }
    }
}

/// Sets `path` in `root` to `value`.
fn set(root: &mut Table, path: &str, value: Value) -> Result<(), KeyError> {
    let bad = |why: String| KeyError::Path {
        path: path.to_string(),
        why,
    };
    if path.split('.').any(str::is_empty) {
        return Err(bad("an empty key".into()));
    }
    let mut segments: Vec<&str> = path.split('.').collect();
    let last = segments.pop().unwrap_or_default();
    let mut table = root;
    for seg in segments {
        let (name, index) = segment(path, seg)?;
        let mut next = table.get_mut(name).ok_or_else(|| bad(format!("the scene has no `{name}`")))?;
        if let Some(i) = index {
            next = next
                .as_array_mut()
                .and_then(|a| a.get_mut(i))
                .ok_or_else(|| bad(format!("the scene has no `{name}[{i}]`")))?;
        }
        table = next.as_table_mut().ok_or_else(|| bad(format!("`{seg}` is not a table")))?;
    }
    match segment(path, last)? {
        // an element of an array, replaced whole
        (name, Some(i)) => {
            let slot = table
                .get_mut(name)
                .and_then(|a| a.as_array_mut())
                .and_then(|a| a.get_mut(i))
                .ok_or_else(|| bad(format!("the scene has no `{last}` to replace")))?;
            *slot = value;
        }
        (name, None) => {
            table.insert(name.to_string(), value);
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    const SCENE: &str = "[[organs]]\nname = \"a\"\n[organs.mesh]\ndivisions = [4, 4, 4]\n\n[[tools]]\nkind = \"probe\"\nradius = 2.0\n";

    #[test]
    fn a_key_is_set_where_its_path_says() {
        let text = with_keys(
            SCENE,
            &[
                ("organs[0].mesh.divisions", "[8, 8, 8]"),
                ("organs[0].mesh.kind", "\"hex8\""),
                ("tools[0]", "{ kind = \"grasper\", max_force = 6.0 }"),
            ],
        )
        .unwrap();
        let t: Table = toml::from_str(&text).unwrap();
        let organ = &t["organs"][0];
        assert_eq!(organ["mesh"]["divisions"].as_array().unwrap().len(), 3);
        assert_eq!(organ["mesh"]["divisions"][0].as_integer(), Some(8));
        assert_eq!(organ["mesh"]["kind"].as_str(), Some("hex8"));
        assert_eq!(organ["name"].as_str(), Some("a"));
        assert_eq!(t["tools"][0]["kind"].as_str(), Some("grasper"));
        assert!(t["tools"][0].get("radius").is_none(), "the element is replaced whole");
    }

    #[test]
    fn a_path_that_leads_nowhere_is_an_error_not_a_silent_edit() {
        for (path, why) in [
            ("organs[1].mesh.divisions", "organs[1]"),
            ("organ[0].mesh.divisions", "no `organ`"),
            ("organs[0].name.x", "not a table"),
            ("tools[3]", "tools[3]"),
            ("organs[x].mesh", "name[index]"),
            ("organs..mesh", "empty key"),
        ] {
            let e = with_keys(SCENE, &[(path, "1")]).unwrap_err().to_string();
            assert!(e.contains(why), "{path}: {e}");
        }
        assert!(matches!(
            with_keys(SCENE, &[("organs[0].name", "[1,")]),
            Err(KeyError::Value { .. })
        ));
        assert!(matches!(with_keys("[[organs]", &[]), Err(KeyError::Scene(_))));
    }
}
