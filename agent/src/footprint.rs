//! An agent's share of the binary's code. A process maps the code it runs in 64 KiB pieces
//! (the kernel maps the pages around each one it touches), and an agent touches much of the
//! binary once, as it starts (its Zenoh session, its TLS, its configuration), then a small part
//! again and again. Once it runs, it lets go of its mapping of the code: the pages stay in the
//! page cache, shared, and those it runs again come back at their next touch, so its resident
//! set holds its running code, not its start.

/// Drops this process's mapping of its own executable's code; how many KiB it held before.
/// Only the executable segment: it is never written (a position-independent executable has no
/// text relocations), so dropping it loses nothing but page-table entries, which come back on
/// the next touch. Linux only; elsewhere, and if /proc cannot say, it does nothing.
pub fn drop_startup_code() -> Option<u64> {
    let exe = std::fs::read_link("/proc/self/exe").ok()?;
    let maps = std::fs::read_to_string("/proc/self/maps").ok()?;
    let mut dropped = 0;
    for line in maps.lines() {
        let mut fields = line.split_whitespace();
        let (Some(range), Some(perms)) = (fields.next(), fields.next()) else {
            continue;
        };
        if perms != "r-xp" || fields.nth(3).map(std::path::Path::new) != Some(exe.as_path()) {
            continue;
        }
        let Some((start, end)) = range.split_once('-') else {
            continue;
        };
        let (Ok(start), Ok(end)) = (usize::from_str_radix(start, 16), usize::from_str_radix(end, 16)) else {
            continue;
        };
        // SAFETY: the range is a mapping of this process's own executable code, which nothing
        // writes; MADV_DONTNEED on it only unmaps clean file pages, faulted in again on use.
        if unsafe { libc::madvise(start as *mut libc::c_void, end - start, libc::MADV_DONTNEED) } == 0 {
            dropped += (end - start) as u64 / 1024;
        }
    }
    Some(dropped)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_process_that_lets_go_of_its_code_runs_on() {
        let kib = drop_startup_code().expect("Linux says where the code is");
        assert!(kib > 256, "the test binary's code is hundreds of KiB: {kib} KiB");
        // Code not run since comes back on its touch: a collection, a thread, a format.
        let back: std::collections::BTreeMap<u32, f64> = [(1, 2.5), (3, 0.125)].into();
        let joined = std::thread::spawn(move || format!("{back:?} {:e}", 1500.0))
            .join()
            .unwrap();
        assert_eq!(joined, "{1: 2.5, 3: 0.125} 1.5e3");
        assert!(drop_startup_code().is_some(), "and can let go again");
    }
}
