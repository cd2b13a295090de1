//! A fleet's credentials for roles started by hand, made by `tcpf credential`.
//!
//! - **One per role** (`tcpf credential DIR MISSION`): a fleet directory holding, for each role
//!   of the mission (`acl::identities`), `<identity>.key` with its own user and password; the
//!   `credentials` dictionary of them all and the access rules made from the mission
//!   (`access.json5`), which the router (`tcpf router --credential DIR`) demands and enforces. A
//!   host holds only its own role's key, and with it can speak only as that role.
//! - **One for the whole fleet** (`tcpf credential FILE`): one user and password, in a file that
//!   is at once what a process presents (`transport/auth/usrpwd/user`, `password`) and what it
//!   demands of others (the `dictionary_file`). Whoever holds it may speak for every role: for a
//!   fleet whose every host is trusted.

use std::io::{Read, Write};
use std::os::unix::fs::{DirBuilderExt, OpenOptionsExt, PermissionsExt};
use std::path::Path;

use anyhow::{Context, Result};

use crate::acl::{self, Fleet, Identity, Naming};

/// The user every process of a fleet presents.
pub const USER: &str = "tcpf";

/// 128 bits from the kernel, in hex: a password nobody can guess in a fleet's lifetime.
pub fn secret() -> Result<String> {
    let mut bytes = [0u8; 16];
    std::fs::File::open("/dev/urandom")
        .and_then(|mut f| f.read_exact(&mut bytes))
        .context("cannot read /dev/urandom for a credential")?;
    Ok(bytes.iter().map(|b| format!("{b:02x}")).collect())
}

/// Writes `contents` to a new file that only its owner may read; an existing file is left as
/// it is (a credential overwritten would lock every host that holds the old one out).
pub fn private(path: &Path, contents: &str) -> Result<()> {
    std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .mode(0o600)
        .open(path)
        .and_then(|mut f| f.write_all(contents.as_bytes()))
        .with_context(|| format!("cannot write {}", path.display()))
}

/// Makes a new credential file at `path`: the password it holds.
pub fn create(path: &Path) -> Result<String> {
    let password = secret()?;
    private(path, &format!("{USER}:{password}\n"))?;
    Ok(password)
}

/// A fleet directory's dictionary of every role's user and password, for the router.
pub const DICTIONARY: &str = "credentials";
/// A fleet directory's access rules (Zenoh's `access_control` section), for the router.
pub const ACCESS: &str = "access.json5";

/// The file of `identity`'s key in a fleet directory.
pub fn key_file(identity: Identity) -> String {
    format!("{identity}.key")
}

/// Makes the fleet directory `dir` (new, owner-only) for `fleet`: a key per role, the dictionary
/// and the access rules, by user name. Returns the roles, in the order of their keys.
pub fn create_fleet(dir: &Path, fleet: &Fleet) -> Result<Vec<Identity>> {
    std::fs::DirBuilder::new()
        .mode(0o700)
        .create(dir)
        .with_context(|| format!("cannot make {}", dir.display()))?;
    let identities = acl::identities(fleet);
    let mut dictionary = String::new();
    for &identity in &identities {
        let line = format!("{identity}:{}\n", secret()?);
        private(&dir.join(key_file(identity)), &line)?;
        dictionary.push_str(&line);
    }
    private(&dir.join(DICTIONARY), &dictionary)?;
    let access = acl::access_control(fleet, Naming::Username);
    private(&dir.join(ACCESS), &(serde_json::to_string_pretty(&access)? + "\n"))?;
    Ok(identities)
}

/// What a router takes from the fleet directory `dir`: the dictionary's path and the access
/// rules, or why they cannot be had.
pub fn read_fleet(dir: &Path) -> std::result::Result<(std::path::PathBuf, serde_json::Value), String> {
    let private_file = |path: &Path| {
        std::fs::metadata(path)
            .map_err(|e| e.to_string())
            .and_then(|meta| owner_only(&meta, path))
            .map_err(|why| format!("{}: {why}", path.display()))
    };
    let dictionary = dir.join(DICTIONARY);
    private_file(&dictionary)?;
    let access = dir.join(ACCESS);
    private_file(&access)?;
    let at = |why: String| format!("{}: {why}", access.display());
    let text = std::fs::read_to_string(&access).map_err(|e| at(e.to_string()))?;
    let rules: serde_json::Value = serde_json::from_str(&text).map_err(|e| at(e.to_string()))?;
    // Rules switched off, or allowing by default, would let every key speak for every role.
    if rules["enabled"] != true || rules["default_permission"] != "deny" {
        return Err(at(
            "its rules must be enabled and deny by default (`enabled: true`, `default_permission: \"deny\"`), as `tcpf credential DIR MISSION` writes them"
                .into(),
        ));
    }
    Ok((dictionary, rules))
}

/// Refuses a file that others may read, as ssh refuses such a key: anyone who reads it could
/// speak for the roles it names.
fn owner_only(meta: &std::fs::Metadata, path: &Path) -> std::result::Result<(), String> {
    let mode = meta.permissions().mode() & 0o777;
    if mode & 0o077 != 0 {
        return Err(format!(
            "others may read it (mode {mode:03o}); `chmod 600 {}` and keep it so",
            path.display()
        ));
    }
    Ok(())
}

/// The user and password of the credential file at `path`, or why it cannot be one: a file that
/// others may read is refused, as ssh refuses such a key, since anyone who reads it can speak
/// for every role of the fleet.
pub fn read(path: &Path) -> std::result::Result<(String, String), String> {
    let meta = std::fs::metadata(path).map_err(|e| e.to_string())?;
    if meta.is_dir() {
        return Err(format!(
            "a directory, not a file: a fleet directory of `tcpf credential DIR MISSION` is the router's; a role takes its own key, {}",
            path.join("<role>.key").display()
        ));
    }
    owner_only(&meta, path)?;
    let text = std::fs::read_to_string(path).map_err(|e| e.to_string())?;
    let mut lines = text.lines().map(str::trim).filter(|l| !l.is_empty());
    let line = lines.next().unwrap_or("");
    // The file is also the dictionary every listener checks others against: each further line
    // would be another user it lets in, unseen.
    if lines.next().is_some() {
        return Err(
            "more than one line: a key is one USER:PASSWORD, and every further line would be a user let in (make them with `tcpf credential DIR MISSION`)"
                .into(),
        );
    }
    match line.split_once(':') {
        Some((user, password)) if !user.is_empty() && !password.is_empty() => {
            Ok((user.to_string(), password.to_string()))
        }
        _ => {
            Err("not a credential: its first line must be USER:PASSWORD (make a key per role with `tcpf credential DIR MISSION`)".into())
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> std::path::PathBuf {
        let dir = std::env::temp_dir().join(format!("tcpf-credential-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir.join("fleet.key")
    }

    #[test]
    fn a_new_credential_reads_back_and_is_owner_only() {
        let path = scratch("new");
        let password = create(&path).unwrap();
        assert_eq!(password.len(), 32);
        assert_eq!(read(&path).unwrap(), (USER.to_string(), password));
        let mode = std::fs::metadata(&path).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode, 0o600);
        let again = create(&path).unwrap_err().to_string();
        assert!(again.contains("cannot write"), "{again}");
        assert_eq!(read(&path).unwrap().0, USER, "an existing credential is kept");
    }

    #[test]
    fn a_credential_others_can_read_or_without_a_password_is_refused() {
        let path = scratch("open");
        std::fs::write(&path, "tcpf:secret\n").unwrap();
        std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o644)).unwrap();
        let why = read(&path).unwrap_err();
        assert!(why.contains("mode 644") && why.contains("chmod 600"), "{why}");
        std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o600)).unwrap();
        assert_eq!(read(&path).unwrap(), ("tcpf".into(), "secret".into()));
        std::fs::write(&path, "tcpf\n").unwrap();
        assert!(read(&path).unwrap_err().contains("USER:PASSWORD"));
        std::fs::write(&path, "tcpf:secret\nmallory:open\n").unwrap();
        let why = read(&path).unwrap_err();
        assert!(why.starts_with("more than one line"), "{why}");
    }
}
