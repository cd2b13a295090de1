//! A fresh Zenoh user and password for each `tcpf run`. Every node of the fleet demands them of
//! every link (Zenoh's user-password authentication), so only processes that can read the run
//! directory's owner-only files can join: another user's process, or one that merely knows the
//! port, cannot publish into the run.

use std::io::{Read, Write};
use std::os::unix::fs::OpenOptionsExt;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use serde_json::json;

/// The user every process of a run presents.
const USER: &str = "tcpf";

/// 128 bits from the kernel, in hex: a password nobody can guess in a run's lifetime.
fn secret() -> Result<String> {
    let mut bytes = [0u8; 16];
    std::fs::File::open("/dev/urandom")
        .and_then(|mut f| f.read_exact(&mut bytes))
        .context("cannot read /dev/urandom for the run's credential")?;
    Ok(bytes.iter().map(|b| format!("{b:02x}")).collect())
}

/// Writes `contents` to a new file that only its owner may read.
fn private(path: &Path, contents: &str) -> Result<()> {
    std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .mode(0o600)
        .open(path)
        .and_then(|mut f| f.write_all(contents.as_bytes()))
        .with_context(|| format!("cannot write {}", path.display()))
}

/// Writes the run's credential (`credentials`, Zenoh's user-password dictionary) and the Zenoh
/// configuration that joins the run with it (`zenoh.json5`: a client of the launcher's router at
/// `endpoint`), both owner-only, into `dir`. Returns the configuration's path.
///
/// Clients of one router, not peers: peers that find each other by gossip open links both ways,
/// and with user-password authentication Zenoh 1.10 refuses the second (eclipse-zenoh/zenoh#2577),
/// which under load can leave a process without a link. A router also keeps the sockets of a
/// fleet linear in its size.
pub fn create(dir: &Path, endpoint: &str) -> Result<PathBuf> {
    let password = secret()?;
    let dictionary = dir.join("credentials");
    private(&dictionary, &format!("{USER}:{password}\n"))?;
    let dictionary = std::fs::canonicalize(&dictionary)?;
    let config = json!({
        "mode": "client",
        "scouting": { "multicast": { "enabled": false } },
        "connect": { "endpoints": [endpoint] },
        "transport": { "auth": { "usrpwd": {
            "user": USER,
            "password": password,
            "dictionary_file": dictionary,
        } } },
    });
    let file = dir.join("zenoh.json5");
    private(&file, &(serde_json::to_string_pretty(&config)? + "\n"))?;
    Ok(file)
}

/// Writes `endpoint` (owner-only) into `dir` once the router listens there: its existence says
/// that the run can be joined.
pub fn announce(dir: &Path, endpoint: &str) -> Result<()> {
    private(&dir.join("endpoint"), &format!("{endpoint}\n"))
}
