//! A fleet's credentials for roles started by hand, made by `tcpf credential`.
//!
//! - **One per role** (`tcpf credential DIR MISSION`): a fleet directory holding, for each role
//!   of the mission (`acl::identities`), `<identity>.pem` with its own certificate, its key and
//!   the fleet's authority (mutual TLS, `certificate`); `router.pem`, the router's, valid where
//!   it listens; and the access rules made from the mission (`access.json5`), which the router
//!   (`tcpf router --credential DIR`) demands and enforces. A host holds only its own role's
//!   file, and with it can speak only as that role. With `--passwords`, `<identity>.key` holds a
//!   user and password instead, and `credentials` the router's dictionary of them all, for a
//!   Zenoh without TLS.
//! - **One for the whole fleet** (`tcpf credential FILE`): one user and password, in a file that
//!   is at once what a process presents (`transport/auth/usrpwd/user`, `password`) and what it
//!   demands of others (the `dictionary_file`). Whoever holds it may speak for every role: for a
//!   fleet whose every host is trusted.

use std::io::{Read, Write};
use std::os::unix::fs::{DirBuilderExt, OpenOptionsExt, PermissionsExt};
use std::path::Path;

use crate::acl::{self, Fleet, Identity, Naming};
use crate::certificate::{Authority, Bundle};
use crate::error::{Context, Result};

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

/// A fleet directory's router certificate file.
pub const ROUTER: &str = "router.pem";

/// Where a router is reached, besides the hosts given: this host, by name and address.
const HERE: [&str; 2] = ["localhost", "127.0.0.1"];

/// How the roles of a fleet started by hand prove which they are.
#[derive(Debug, Clone, Copy)]
pub enum Proof<'a> {
    /// A certificate per role; the router's valid at `hosts` and on this host.
    Certificates { hosts: &'a [String] },
    /// A user and password per role.
    Passwords,
}

/// The file of `identity`'s credential in a fleet directory.
pub fn key_file(identity: Identity, proof: Proof) -> String {
    match proof {
        Proof::Certificates { .. } => format!("{identity}.pem"),
        Proof::Passwords => format!("{identity}.key"),
    }
}

/// Makes the fleet directory `dir` (new, owner-only) for `fleet`, named `name`: a credential per
/// role, the router's, and the access rules. Returns the roles, in the order of their files.
pub fn create_fleet(dir: &Path, name: &str, fleet: &Fleet, proof: Proof) -> Result<Vec<Identity>> {
    std::fs::DirBuilder::new()
        .mode(0o700)
        .create(dir)
        .with_context(|| format!("cannot make {}", dir.display()))?;
    let identities = acl::identities(fleet);
    let naming = match proof {
        Proof::Certificates { hosts } => {
            let authority = Authority::new(name)?;
            let bundle = |name: &str, hosts: &[String]| -> Result<String> {
                let pair = authority.issue(name, hosts)?;
                Ok(Bundle {
                    pair,
                    authority: authority.pem(),
                }
                .pem())
            };
            for &identity in &identities {
                private(
                    &dir.join(key_file(identity, proof)),
                    &bundle(&identity.to_string(), &[])?,
                )?;
            }
            let mut at: Vec<String> = HERE.iter().map(|h| h.to_string()).collect();
            at.extend(hosts.iter().filter(|h| !HERE.contains(&h.as_str())).cloned());
            private(&dir.join(ROUTER), &bundle("router", &at)?)?;
            Naming::CommonName
        }
        Proof::Passwords => {
            let mut dictionary = String::new();
            for &identity in &identities {
                let line = format!("{identity}:{}\n", secret()?);
                private(&dir.join(key_file(identity, proof)), &line)?;
                dictionary.push_str(&line);
            }
            private(&dir.join(DICTIONARY), &dictionary)?;
            Naming::Username
        }
    };
    let access = acl::access_control(fleet, naming);
    private(
        &dir.join(ACCESS),
        &(serde_json::to_string_pretty(&access).context("cannot write the access rules")? + "\n"),
    )?;
    Ok(identities)
}

/// What a router of a fleet directory demands of every link.
pub enum Demand {
    /// A certificate of the fleet's authority: the router presents its own, in this file.
    Certificate(Bundle),
    /// One of the users and passwords of this dictionary.
    Dictionary(std::path::PathBuf),
}

/// What a router takes from the fleet directory `dir`: what it demands and the access rules, or
/// why they cannot be had.
pub fn read_fleet(dir: &Path) -> std::result::Result<(Demand, serde_json::Value), String> {
    let private_file = |path: &Path| {
        std::fs::metadata(path)
            .map_err(|e| e.to_string())
            .and_then(|meta| owner_only(&meta, path))
            .map_err(|why| format!("{}: {why}", path.display()))
    };
    let router = dir.join(ROUTER);
    let demand = if router.exists() {
        private_file(&router)?;
        match read(&router).map_err(|why| format!("{}: {why}", router.display()))? {
            Credential::Certificate(bundle) => Demand::Certificate(bundle),
            Credential::Password { .. } => return Err(format!("{}: not a certificate", router.display())),
        }
    } else {
        let dictionary = dir.join(DICTIONARY);
        private_file(&dictionary)?;
        Demand::Dictionary(dictionary)
    };
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
    Ok((demand, rules))
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

/// What a credential file holds.
pub enum Credential {
    /// A user and password (`tcpf credential FILE`, or a role's `.key`).
    Password { user: String, password: String },
    /// A certificate, its key and the fleet's authority (a role's `.pem`).
    Certificate(Bundle),
}

/// Names the holder, never the secret: a credential may end up in an error message.
impl std::fmt::Debug for Credential {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Credential::Password { user, .. } => write!(f, "the password of {user}"),
            Credential::Certificate(bundle) => bundle.fmt(f),
        }
    }
}

/// The credential in the file at `path`, or why it cannot be one: a file that others may read
/// is refused, as ssh refuses such a key, since anyone who reads it can speak for a role.
pub fn read(path: &Path) -> std::result::Result<Credential, String> {
    let meta = std::fs::metadata(path).map_err(|e| e.to_string())?;
    if meta.is_dir() {
        return Err(format!(
            "a directory, not a file: a fleet directory of `tcpf credential DIR MISSION` is the router's; a role takes its own file, {}",
            path.join("<role>.pem").display()
        ));
    }
    owner_only(&meta, path)?;
    let text = std::fs::read_to_string(path).map_err(|e| e.to_string())?;
    if text.contains("-----BEGIN ") {
        return Bundle::parse(&text).map(Credential::Certificate);
    }
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
        Some((user, password)) if !user.is_empty() && !password.is_empty() => Ok(Credential::Password {
            user: user.to_string(),
            password: password.to_string(),
        }),
        _ => {
            Err("not a credential: neither a certificate (PEM) nor a line USER:PASSWORD (make one per role with `tcpf credential DIR MISSION`)".into())
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

    fn user_and_password(path: &Path) -> (String, String) {
        match read(path).unwrap() {
            Credential::Password { user, password } => (user, password),
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn a_new_credential_reads_back_and_is_owner_only() {
        let path = scratch("new");
        let password = create(&path).unwrap();
        assert_eq!(password.len(), 32);
        assert_eq!(user_and_password(&path), (USER.to_string(), password));
        let mode = std::fs::metadata(&path).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode, 0o600);
        let again = create(&path).unwrap_err().to_string();
        assert!(again.contains("cannot write"), "{again}");
        assert_eq!(user_and_password(&path).0, USER, "an existing credential is kept");
    }

    #[test]
    fn a_credential_others_can_read_or_without_a_password_is_refused() {
        let path = scratch("open");
        std::fs::write(&path, "tcpf:secret\n").unwrap();
        std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o644)).unwrap();
        let why = read(&path).unwrap_err();
        assert!(why.contains("mode 644") && why.contains("chmod 600"), "{why}");
        std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o600)).unwrap();
        assert_eq!(user_and_password(&path), ("tcpf".into(), "secret".into()));
        std::fs::write(&path, "tcpf\n").unwrap();
        assert!(read(&path).unwrap_err().contains("USER:PASSWORD"));
        std::fs::write(&path, "tcpf:secret\nmallory:open\n").unwrap();
        let why = read(&path).unwrap_err();
        assert!(why.starts_with("more than one line"), "{why}");
    }
}
