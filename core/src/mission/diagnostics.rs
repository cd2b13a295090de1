//! Where in a mission file something is: file, line and key path, for error messages.

use std::fmt;

use toml::de::{DeTable, DeValue};

/// A mission that cannot be used, with where and why.
#[derive(Debug, Clone, PartialEq)]
pub struct MissionError {
    pub file: String,
    pub line: Option<usize>,
    pub key: Option<String>,
    pub message: String,
}

impl fmt::Display for MissionError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.file)?;
        if let Some(line) = self.line {
            write!(f, ":{line}")?;
        }
        if let Some(key) = &self.key {
            write!(f, ": key `{key}`")?;
        }
        write!(f, ": {}", self.message)
    }
}

impl std::error::Error for MissionError {}

/// One step of a key path: a table key or an array index.
#[derive(Debug, Clone, PartialEq)]
pub(super) enum Seg {
    Key(String),
    Index(usize),
}

pub(super) fn path_string(path: &[Seg]) -> String {
    path_below(String::new(), path)
}

/// `key` and then `path`, a path below it: `comms.link` and `[0].loss`.
pub(super) fn path_below(key: String, path: &[Seg]) -> String {
    let mut s = key;
    for seg in path {
        match seg {
            Seg::Key(k) if s.is_empty() => s.push_str(k),
            Seg::Key(k) => {
                s.push('.');
                s.push_str(k);
            }
            Seg::Index(i) => s.push_str(&format!("[{i}]")),
        }
    }
    s
}

pub(super) fn line_of(text: &str, offset: usize) -> usize {
    text[..offset.min(text.len())].bytes().filter(|&b| b == b'\n').count() + 1
}

/// The innermost key whose key or value covers `offset`, as a path. Every branch is searched:
/// a table's own span covers only its header, not the keys under it.
pub(super) fn key_at(table: &DeTable<'_>, offset: usize) -> Vec<Seg> {
    fn covers(r: std::ops::Range<usize>, offset: usize) -> bool {
        r.start <= offset && offset < r.end.max(r.start + 1)
    }
    fn walk(value: &DeValue<'_>, offset: usize, path: &mut Vec<Seg>) -> bool {
        let depth = path.len();
        match value {
            DeValue::Table(t) => {
                for (k, v) in t.iter() {
                    path.push(Seg::Key(k.get_ref().to_string()));
                    if walk(v.get_ref(), offset, path) || covers(k.span(), offset) || covers(v.span(), offset) {
                        return true;
                    }
                    path.truncate(depth);
                }
            }
            DeValue::Array(a) => {
                for (i, v) in a.iter().enumerate() {
                    path.push(Seg::Index(i));
                    if walk(v.get_ref(), offset, path) {
                        return true;
                    }
                    path.truncate(depth);
                }
            }
            _ => {}
        }
        false
    }
    let mut path = Vec::new();
    walk(&DeValue::Table(table.clone()), offset, &mut path);
    path
}

/// Where the key at `path` is, or the nearest table above it that the file has.
pub(super) fn line_of_key(text: &str, table: &DeTable<'_>, path: &[Seg]) -> Where {
    let mut value: Option<&DeValue<'_>> = None;
    let mut span = None;
    let mut current = table;
    let mut whole = true;
    for seg in path {
        let found = match (seg, value) {
            (Seg::Key(k), None) | (Seg::Key(k), Some(DeValue::Table(_))) => {
                if let Some(DeValue::Table(t)) = value {
                    current = t;
                }
                current
                    .iter()
                    .find(|(key, _)| key.get_ref() == k)
                    .map(|(key, v)| (key.span(), v.get_ref()))
            }
            (Seg::Index(i), Some(DeValue::Array(a))) => a.get(*i).map(|v| (v.span(), v.get_ref())),
            _ => None,
        };
        let Some((s, v)) = found else {
            whole = false;
            break;
        };
        span = Some(s);
        value = Some(v);
    }
    Where {
        line: span.map(|s| line_of(text, s.start)),
        defaulted: !whole,
    }
}

/// Where a key is in the file: its line, or that of the nearest table above it that the file
/// has when the key itself is not there (`defaulted`: its default is what was found wrong).
pub(super) struct Where {
    pub line: Option<usize>,
    pub defaulted: bool,
}
