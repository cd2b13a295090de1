//! A sweep's grid: the keys it sets and their values, its seeds, which run is which, and the
//! share of the runs a shard takes. Everything here is fixed by the command line alone, so that
//! any shard, rerun alone on any machine, runs the same runs as the first time.

use std::fmt;

use serde::{Deserialize, Serialize};

/// A swept mission key and its values, as given (`--param KEY=V1,V2,...`).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Param {
    pub key: String,
    pub values: Vec<String>,
}

/// Every combination of the params' values (a grid point), each run with seeds `seed_start` to
/// `seed_start + seeds − 1`.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Grid {
    pub params: Vec<Param>,
    pub seeds: u64,
    pub seed_start: u64,
}

impl Grid {
    pub fn points(&self) -> u64 {
        self.params.iter().map(|p| p.values.len() as u64).product()
    }

    pub fn runs(&self) -> u64 {
        self.points() * self.seeds
    }

    /// Run `k`: its grid point and seed. Points run in the order of the params (the last key
    /// changes fastest), each through all its seeds.
    pub fn run(&self, k: u64) -> (u64, u64) {
        (k / self.seeds, self.seed_start + k % self.seeds)
    }

    /// The index of each param's value at `point`.
    pub fn indices(&self, point: u64) -> Vec<usize> {
        let mut rest = point;
        let mut at = vec![0; self.params.len()];
        for (i, p) in self.params.iter().enumerate().rev() {
            let n = p.values.len() as u64;
            at[i] = (rest % n) as usize;
            rest /= n;
        }
        at
    }

    /// The values of `point`, one per param.
    pub fn values(&self, point: u64) -> Vec<&str> {
        self.indices(point)
            .iter()
            .zip(&self.params)
            .map(|(&i, p)| p.values[i].as_str())
            .collect()
    }

    /// `key = value` of every param at `point`, as a table or an error names it.
    pub fn label(&self, point: u64) -> String {
        self.params
            .iter()
            .zip(self.values(point))
            .map(|(p, v)| format!("{} = {v}", p.key))
            .collect::<Vec<_>>()
            .join(", ")
    }

    /// The flags that give this grid on the command line, each value quoted for a POSIX shell.
    pub fn flags(&self) -> Vec<String> {
        let mut flags = Vec::new();
        for p in &self.params {
            flags.push("--param".to_string());
            flags.push(shell_quote(&format!("{}={}", p.key, p.values.join(","))));
        }
        flags.extend([
            "--seeds".into(),
            self.seeds.to_string(),
            "--seed-start".into(),
            self.seed_start.to_string(),
        ]);
        flags
    }
}

/// `s` as one word of a POSIX shell.
pub fn shell_quote(s: &str) -> String {
    if !s.is_empty() && s.chars().all(|c| c.is_ascii_alphanumeric() || "-_.,=/:+@%".contains(c)) {
        s.to_string()
    } else {
        format!("'{}'", s.replace('\'', "'\\''"))
    }
}

/// The values of `--param KEY=V1,V2,...`, split at the commas that separate values: not those
/// inside brackets, braces or quotes, so a list or a table is one value.
pub fn split_values(list: &str) -> Result<Vec<String>, String> {
    let mut values = Vec::new();
    let mut depth = 0i32;
    let mut quote: Option<char> = None;
    let mut current = String::new();
    for c in list.chars() {
        match (quote, c) {
            (Some(q), c) if c == q => quote = None,
            (Some(_), _) => {}
            (None, '"' | '\'') => quote = Some(c),
            (None, '[' | '{') => depth += 1,
            (None, ']' | '}') => {
                depth -= 1;
                if depth < 0 {
                    return Err(format!("{list}: a {c} closes nothing"));
                }
            }
            (None, ',') if depth == 0 => {
                values.push(current.trim().to_string());
                current.clear();
                continue;
            }
            _ => {}
        }
        current.push(c);
    }
    if quote.is_some() || depth != 0 {
        return Err(format!("{list}: a quote, bracket or brace is left open"));
    }
    values.push(current.trim().to_string());
    Ok(values)
}

/// Shard `index` of `count`: the runs `k` with `k mod count = index − 1`. Round robin, so each
/// shard gets a like share of every grid point, and slow points do not all land on one shard.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Shard {
    pub index: u64,
    pub count: u64,
}

impl Shard {
    pub fn parse(s: &str) -> Result<Shard, String> {
        let bad = || format!("--shard {s}: expected I/K with 1 ≤ I ≤ K, e.g. 2/8");
        let (i, k) = s.split_once('/').ok_or_else(bad)?;
        let (index, count) = (
            i.trim().parse::<u64>().map_err(|_| bad())?,
            k.trim().parse::<u64>().map_err(|_| bad())?,
        );
        if index == 0 || index > count {
            return Err(bad());
        }
        Ok(Shard { index, count })
    }

    pub fn holds(&self, run: u64) -> bool {
        run % self.count == self.index - 1
    }

    /// How many of `runs` runs are this shard's.
    pub fn share(&self, runs: u64) -> u64 {
        runs / self.count + u64::from(runs % self.count >= self.index)
    }
}

impl fmt::Display for Shard {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid() -> Grid {
        Grid {
            params: vec![
                Param {
                    key: "comms.loss".into(),
                    values: vec!["0".into(), "0.3".into(), "0.6".into()],
                },
                Param {
                    key: "comms.delay".into(),
                    values: vec!["0".into(), "1".into()],
                },
            ],
            seeds: 5,
            seed_start: 11,
        }
    }

    #[test]
    fn runs_go_point_by_point_the_last_key_fastest_each_through_its_seeds() {
        let g = grid();
        assert_eq!((g.points(), g.runs()), (6, 30));
        assert_eq!(g.run(0), (0, 11));
        assert_eq!(g.run(7), (1, 13));
        assert_eq!(g.values(1), ["0", "1"]);
        assert_eq!(g.values(2), ["0.3", "0"]);
        assert_eq!(g.values(5), ["0.6", "1"]);
        assert_eq!(g.label(3), "comms.loss = 0.3, comms.delay = 1");
    }

    #[test]
    fn shards_take_every_run_once_whatever_their_number() {
        let runs = grid().runs();
        for count in 1..=9 {
            let shards: Vec<Shard> = (1..=count).map(|index| Shard { index, count }).collect();
            for k in 0..runs {
                assert_eq!(
                    shards.iter().filter(|s| s.holds(k)).count(),
                    1,
                    "run {k} of {count} shards"
                );
            }
            for s in &shards {
                assert_eq!(s.share(runs), (0..runs).filter(|&k| s.holds(k)).count() as u64);
            }
        }
        assert_eq!(Shard::parse("2/7"), Ok(Shard { index: 2, count: 7 }));
        for bad in ["0/3", "4/3", "3", "a/b", "1/0"] {
            assert!(Shard::parse(bad).unwrap_err().contains("expected I/K"), "{bad}");
        }
    }

    #[test]
    fn lists_and_tables_are_one_value_each() {
        assert_eq!(split_values("0, 0.3,0.6").unwrap(), ["0", "0.3", "0.6"]);
        assert_eq!(
            split_values("[[1,2],[2,3]],[[1,3]]").unwrap(),
            ["[[1,2],[2,3]]", "[[1,3]]"]
        );
        assert_eq!(
            split_values("[{ from = 1, to = 2, delay = 1.0 }],[]").unwrap(),
            ["[{ from = 1, to = 2, delay = 1.0 }]", "[]"]
        );
        assert_eq!(split_values("\"a,b\",ring").unwrap(), ["\"a,b\"", "ring"]);
        assert!(split_values("[1,2").unwrap_err().contains("left open"));
        assert!(split_values("1],2").unwrap_err().contains("closes nothing"));
    }

    #[test]
    fn the_flags_give_the_grid_back_through_a_shell() {
        let mut g = grid();
        g.params.push(Param {
            key: "comms.link".into(),
            values: vec!["[{ from = 1, to = 2, delay = 1.0 }]".into(), "[]".into()],
        });
        let flags = g.flags();
        assert_eq!(flags[1], "comms.loss=0,0.3,0.6");
        assert_eq!(flags[5], "'comms.link=[{ from = 1, to = 2, delay = 1.0 }],[]'");
        assert_eq!(&flags[6..], ["--seeds", "5", "--seed-start", "11"]);
        assert_eq!(shell_quote("it's"), "'it'\\''s'");
    }
}
