//! `--set section.key=value` (`section.table.key=value` in a table of a section, and
//! `vehicle.<id>.key=value`) applied to a parsed mission file.

use super::diagnostics::Seg;
use super::{Mission, MissionError};

/// Whether the override `o` set the key at `path`, so that an error there names it.
pub(super) fn touches(o: &str, path: &[Seg], mission: &Mission) -> bool {
    let Some((key, _)) = o.split_once('=') else {
        return false;
    };
    let parts: Vec<&str> = key.trim().split('.').collect();
    match (parts.as_slice(), path) {
        // A vehicle's key, or a key below it when the override set a table whole.
        (["vehicle", id, k], [Seg::Key(v), Seg::Index(i), Seg::Key(pk), ..]) if v == "vehicle" => {
            mission.vehicles.get(*i).is_some_and(|veh| id.parse() == Ok(veh.id)) && k == pk
        }
        (["vehicle", ..], _) => false,
        (keys, _) => {
            keys.len() >= 2
                && path.len() >= keys.len()
                && keys.iter().zip(path).all(|(k, p)| matches!(p, Seg::Key(pk) if pk == k))
        }
    }
}

/// The lists of tables below a section, which a `--set` key cannot address element by element
/// (no id names one), each with a whole list to show.
const LISTS: [(&str, &str); 2] = [
    ("comms.link", "[{ from = 1, to = 2, loss = 0.5 }]"),
    ("comms.outage", "[{ from = 1, to = \"*\", start = 10.0, end = 30.0 }]"),
];

/// Applies each override, `set` (`key=value`), which an error names as the user gave it, `said`
/// (`--set key=value`, or the flag that stands for it).
pub(super) fn apply(file: &str, text: &str, overrides: &[super::Override]) -> Result<Mission, MissionError> {
    let mut root: toml::Table = toml::from_str(text).expect("the file parsed once already");
    let mut failing = None;
    for super::Override { set: o, said } in overrides {
        let bad = |message: String| MissionError {
            file: file.to_string(),
            line: None,
            key: Some(o.split('=').next().unwrap_or(o).trim().to_string()),
            message: format!("{said}: {message}"),
        };
        let (key, raw) = o.split_once('=').ok_or_else(|| bad("expected KEY=VALUE".into()))?;
        // A value is one line: what a newline would add (a table header, another key) would be
        // parsed as part of the file and then dropped.
        if raw.contains(['\n', '\r']) {
            return Err(bad("a value is one line: set each key with a --set of its own".into()));
        }
        // A bare word that is no TOML value is taken as a string, so `--set mission.name=x` works.
        let value = toml::from_str::<toml::Table>(&format!("v = {}", raw.trim()))
            .ok()
            .and_then(|mut t| t.remove("v"))
            .unwrap_or_else(|| toml::Value::String(raw.trim().to_string()));
        let parts: Vec<&str> = key.trim().split('.').collect();
        let (table, k) = match parts.as_slice() {
            ["vehicle", id, k] => {
                let id: i64 = id.parse().map_err(|_| bad(format!("`{id}` is not a vehicle id")))?;
                let vehicles = root.get_mut("vehicle").and_then(|v| v.as_array_mut());
                let vehicle = vehicles
                    .and_then(|vs| {
                        vs.iter_mut()
                            .find(|v| v.get("id").and_then(|i| i.as_integer()) == Some(id))
                    })
                    .and_then(|v| v.as_table_mut())
                    .ok_or_else(|| bad(format!("no vehicle with id {id}")))?;
                (vehicle, *k)
            }
            [tables @ .., k] if !tables.is_empty() && tables[0] != "vehicle" => {
                if let Some((list, example)) = LISTS
                    .iter()
                    .find(|(list, _)| key.trim().starts_with(&format!("{list}.")))
                {
                    return Err(bad(format!(
                        "`{list}` is a list of tables ([[{list}]] in the file), and --set cannot name one \
                         of them: set the whole list, as in --set '{list}={example}', or edit the file"
                    )));
                }
                let mut table = &mut root;
                for (n, name) in tables.iter().enumerate() {
                    table = table
                        .entry(name.to_string())
                        .or_insert_with(|| toml::Value::Table(toml::Table::new()))
                        .as_table_mut()
                        .ok_or_else(|| bad(format!("`{}` is not a table", tables[..=n].join("."))))?;
                }
                (table, *k)
            }
            _ => {
                return Err(bad(
                    "keys are `section.key`, `section.table.key` or `vehicle.<id>.key`".into()
                ))
            }
        };
        table.insert(k.to_string(), value);
        // Each override is checked as it is applied, so that an error names the one at fault;
        // but a table set key by key is whole only after its last key, so a failure stands only
        // if no later override mends it.
        failing = match toml::Value::Table(root.clone()).try_into::<Mission>() {
            Ok(_) => None,
            Err(e) => failing.or_else(|| Some(bad(e.message().trim().to_string()))),
        };
    }
    match failing {
        Some(e) => Err(e),
        None => Ok(toml::Value::Table(root)
            .try_into::<Mission>()
            .expect("checked after the last override")),
    }
}
