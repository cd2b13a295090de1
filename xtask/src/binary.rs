//! What a linked `tcpf` is: where it loads, and where the listed functions lie in it.

use std::collections::HashSet;

/// How a binary loads: where the loader chooses (a position-independent executable, which the
/// loader relocates in every process), or at the address it was linked for.
#[derive(Debug, PartialEq, Eq)]
pub enum Load {
    Fixed,
    PositionIndependent,
}

/// Where an ELF file loads, from its header's `e_type`: 2, an executable; 3, a shared object
/// (a position-independent executable is one).
pub fn load(elf: &[u8]) -> Result<Load, String> {
    if elf.len() < 18 || &elf[..4] != b"\x7fELF" {
        return Err("not an ELF file".into());
    }
    let e_type = [elf[16], elf[17]];
    // EI_DATA: 1 little-endian, 2 big-endian.
    let e_type = match elf[5] {
        1 => u16::from_le_bytes(e_type),
        _ => u16::from_be_bytes(e_type),
    };
    match e_type {
        2 => Ok(Load::Fixed),
        3 => Ok(Load::PositionIndependent),
        other => Err(format!("an ELF file of type {other}, neither executable nor shared")),
    }
}

/// A function or object the binary defines, as `nm --defined-only -S` lists it.
#[derive(Debug, PartialEq)]
pub struct Symbol<'a> {
    pub name: &'a str,
    pub address: u64,
    /// None where nm knows none (a symbol the linker made).
    pub size: Option<u64>,
    /// nm's letter: `t`/`T` code, `w`/`W` weak, `d` data, ...
    pub kind: char,
}

impl Symbol<'_> {
    /// Code the binary defines (weak definitions included), which the linker may place.
    pub fn is_code(&self) -> bool {
        matches!(self.kind, 't' | 'T' | 'w' | 'W')
    }
}

/// The symbols of nm's listing: `address size kind name`, or `address kind name` without a size.
pub fn symbols(nm: &str) -> Vec<Symbol<'_>> {
    nm.lines()
        .filter_map(|line| {
            let fields: Vec<&str> = line.split(' ').collect();
            let (address, size, kind, name) = match fields[..] {
                [address, size, kind, name] => (address, Some(size), kind, name),
                [address, kind, name] => (address, None, kind, name),
                _ => return None,
            };
            Some(Symbol {
                name,
                address: u64::from_str_radix(address, 16).ok()?,
                size: match size {
                    Some(size) => Some(u64::from_str_radix(size, 16).ok()?),
                    None => None,
                },
                kind: kind.chars().next()?,
            })
        })
        .collect()
}

/// Where the listed functions lie in a binary.
#[derive(Debug, PartialEq)]
pub struct Layout {
    pub listed: usize,
    /// Listed functions the binary defines.
    pub found: usize,
    /// Their bytes of code (of each function of a name several have).
    pub code: u64,
    /// From the first of them to the end of the last.
    pub span: u64,
}

/// The least share of the list a binary must define: names of rarer paths may be missing from
/// a build, but most missing means the list is of another build.
const FOUND_PERCENT: usize = 95;
/// How far the listed functions may spread past their own size: alignment between them.
const SPAN_PERCENT: u64 = 105;

impl Layout {
    pub fn of(listed: &[String], symbols: &[Symbol]) -> Layout {
        let wanted: HashSet<&str> = listed.iter().map(String::as_str).collect();
        let (mut found, mut start, mut end, mut code) = (HashSet::new(), u64::MAX, 0, 0);
        for symbol in symbols {
            // A local function's name may be several functions' (one per crate or object that
            // has one): the list names them all, and the linker lays them all together.
            if let (true, Some(size)) = (wanted.contains(symbol.name), symbol.size) {
                found.insert(symbol.name);
                start = start.min(symbol.address);
                end = end.max(symbol.address + size);
                code += size;
            }
        }
        Layout {
            listed: wanted.len(),
            found: found.len(),
            code,
            span: end.saturating_sub(start),
        }
    }

    /// Whether the linker took the list: most of its functions are in the binary, side by side.
    pub fn check(&self) -> Result<(), String> {
        let Layout {
            listed,
            found,
            code,
            span,
        } = *self;
        if found * 100 < listed * FOUND_PERCENT {
            return Err(format!(
                "only {found} of the {listed} functions of link-order.txt are in the binary: it lists \
                 another build's (a change of Cargo.lock, features or what an agent runs); \
                 `cargo xtask link-order` makes it anew"
            ));
        }
        if span * 100 > code * SPAN_PERCENT {
            return Err(format!(
                "the listed functions' {code} bytes of code span {span}: the linker did not lay them \
                 side by side"
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn header(class_data: u8, e_type: [u8; 2]) -> Vec<u8> {
        let mut elf = vec![0; 64];
        elf[..4].copy_from_slice(b"\x7fELF");
        elf[5] = class_data;
        elf[16..18].copy_from_slice(&e_type);
        elf
    }

    #[test]
    fn where_an_elf_file_loads_is_its_type() {
        assert_eq!(load(&header(1, [2, 0])), Ok(Load::Fixed));
        assert_eq!(load(&header(1, [3, 0])), Ok(Load::PositionIndependent));
        assert_eq!(load(&header(2, [0, 3])), Ok(Load::PositionIndependent));
        assert!(load(&header(1, [1, 0])).unwrap_err().contains("type 1"));
        assert_eq!(load(b"#!/bin/sh\n...............").unwrap_err(), "not an ELF file");
    }

    #[test]
    fn nms_listing_is_read_with_and_without_sizes() {
        let nm = "0000000000401000 0000000000000020 T main\n\
                  0000000000402000 w weak_one\n\
                  0000000000600000 0000000000000008 d DATA\n\
                  garbage line here and more\n";
        let symbols = symbols(nm);
        assert_eq!(
            symbols[0],
            Symbol {
                name: "main",
                address: 0x401000,
                size: Some(0x20),
                kind: 'T'
            }
        );
        assert_eq!(symbols[1].size, None);
        assert!(symbols[1].is_code());
        assert!(!symbols[2].is_code());
        assert_eq!(symbols.len(), 3);
    }

    fn symbol(name: &str, address: u64, size: u64) -> Symbol<'_> {
        Symbol {
            name,
            address,
            size: Some(size),
            kind: 't',
        }
    }

    fn list(names: &[&str]) -> Vec<String> {
        names.iter().map(|n| n.to_string()).collect()
    }

    #[test]
    fn listed_functions_side_by_side_pass_and_scattered_ones_do_not() {
        let listed = list(&["a", "b", "c"]);
        let together = [
            symbol("a", 0x1000, 0x40),
            symbol("b", 0x1040, 0x40),
            symbol("c", 0x1080, 0x40),
        ];
        let layout = Layout::of(&listed, &together);
        assert_eq!(
            layout,
            Layout {
                listed: 3,
                found: 3,
                code: 0xc0,
                span: 0xc0
            }
        );
        assert_eq!(layout.check(), Ok(()));

        let twice = [
            symbol("a", 0x1000, 0x40),
            symbol("a", 0x1040, 0x40),
            symbol("b", 0x1080, 0x40),
        ];
        let layout = Layout::of(&list(&["a", "b"]), &twice);
        assert_eq!((layout.found, layout.code, layout.span), (2, 0xc0, 0xc0));
        assert_eq!(layout.check(), Ok(()));

        let scattered = [
            symbol("a", 0x1000, 0x40),
            symbol("b", 0x9000, 0x40),
            symbol("c", 0x1080, 0x40),
        ];
        assert!(Layout::of(&listed, &scattered)
            .check()
            .unwrap_err()
            .contains("side by side"));
    }

    #[test]
    fn a_list_of_another_build_is_named_as_such() {
        let listed: Vec<String> = (0..100).map(|i| format!("f{i}")).collect();
        let names: Vec<String> = (0..94).map(|i| format!("f{i}")).collect();
        let symbols: Vec<Symbol> = names
            .iter()
            .enumerate()
            .map(|(i, n)| symbol(n, 0x1000 + 16 * i as u64, 16))
            .collect();
        let layout = Layout::of(&listed, &symbols);
        assert_eq!((layout.found, layout.listed), (94, 100));
        assert!(layout.check().unwrap_err().contains("only 94 of the 100"));
        assert_eq!(Layout::of(&listed[..94], &symbols).check(), Ok(()));
    }
}
