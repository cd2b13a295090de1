//! A fleet's certificate authority and a certificate per role, for mutual TLS: the router knows
//! each link's role by its certificate's Common Name (`acl::Naming::CommonName`), which only the
//! fleet's authority can have signed. A stock ROS 2 (rmw_zenoh, whose Zenoh has TLS but no
//! user-password authentication) can present one.

use base64::Engine;
use rcgen::{
    BasicConstraints, CertificateParams, CertifiedIssuer, DnType, ExtendedKeyUsagePurpose, IsCa, KeyPair,
    KeyUsagePurpose,
};

use serde_json::{json, Value};

use crate::error::{failed, Context, Result};

/// A certificate and its private key, in PEM.
pub struct Pair {
    pub certificate: String,
    pub key: String,
}

/// A fleet's certificate authority: it signs each role's certificate.
pub struct Authority {
    issuer: CertifiedIssuer<'static, KeyPair>,
}

impl Authority {
    /// A new authority for the fleet `fleet`, with a key of its own.
    pub fn new(fleet: &str) -> Result<Self> {
        let mut params = CertificateParams::default();
        params
            .distinguished_name
            .push(DnType::CommonName, format!("tcpf fleet {fleet}"));
        params.is_ca = IsCa::Ca(BasicConstraints::Constrained(0));
        params.key_usages = vec![KeyUsagePurpose::KeyCertSign, KeyUsagePurpose::CrlSign];
        let key = KeyPair::generate().context("cannot make the fleet's authority key")?;
        let issuer = CertifiedIssuer::self_signed(params, key).context("cannot sign the fleet's authority")?;
        Ok(Self { issuer })
    }

    /// The authority's certificate, which every member trusts (`root_ca_certificate`).
    pub fn pem(&self) -> String {
        self.issuer.pem()
    }

    /// A certificate named `name` (an `Identity`, or the router of a fleet started by hand).
    /// `hosts` are the names and addresses a router is reached at: a client checks that the
    /// router it reaches is the one it meant. Only a certificate with hosts may serve as a
    /// router's: a role's cannot pass for one.
    pub fn issue(&self, name: &str, hosts: &[String]) -> Result<Pair> {
        let mut params = CertificateParams::new(hosts.to_vec()).with_context(|| format!("{name}: hosts {hosts:?}"))?;
        params.distinguished_name.push(DnType::CommonName, name);
        params.key_usages = vec![KeyUsagePurpose::DigitalSignature];
        params.extended_key_usages = vec![ExtendedKeyUsagePurpose::ClientAuth];
        if !hosts.is_empty() {
            params.extended_key_usages.push(ExtendedKeyUsagePurpose::ServerAuth);
        }
        let key = KeyPair::generate().with_context(|| format!("cannot make {name}'s key"))?;
        let certificate = params
            .signed_by(&key, &self.issuer)
            .with_context(|| format!("cannot sign {name}'s certificate"))?;
        Ok(Pair {
            certificate: certificate.pem(),
            key: key.serialize_pem(),
        })
    }
}

/// Zenoh's `transport/link/tls` section for a process presenting `pair`, trusting `authority` (its
/// PEM) and demanding a certificate of every link: as a router if it `listens`, else as a client.
/// The certificates and key are inline (base64), so that a role's whole credential is its one
/// owner-only configuration file.
pub fn tls(authority: &str, pair: &Pair, listens: bool) -> Value {
    let inline = |pem: &str| base64::engine::general_purpose::STANDARD.encode(pem);
    let (certificate, key) = match listens {
        true => ("listen_certificate_base64", "listen_private_key_base64"),
        false => ("connect_certificate_base64", "connect_private_key_base64"),
    };
    json!({
        "root_ca_certificate_base64": inline(authority),
        certificate: inline(&pair.certificate),
        key: inline(&pair.key),
        "enable_mtls": true,
    })
}

/// One process's whole credential, as `tcpf credential DIR MISSION` writes it to a file: its
/// certificate, its key and the authority it trusts.
pub struct Bundle {
    pub pair: Pair,
    pub authority: String,
}

impl Bundle {
    /// The bundle as one PEM file.
    pub fn pem(&self) -> String {
        format!("{}{}{}", self.pair.certificate, self.pair.key, self.authority)
    }

    /// The bundle in `text`, or what it lacks: the first certificate is the holder's, the second
    /// its authority's.
    pub fn parse(text: &str) -> std::result::Result<Bundle, String> {
        let mut certificates = Vec::new();
        let mut key = None;
        let mut rest = text;
        while let Some(at) = rest.find("-----BEGIN ") {
            // The label is the rest of the header's line, and only capitals and spaces: nothing
            // of a key's body ever gets into a message.
            let line = rest[at + 11..].lines().next().unwrap_or("");
            let label = line
                .strip_suffix("-----")
                .filter(|l| !l.is_empty() && l.bytes().all(|b| b.is_ascii_uppercase() || b == b' '))
                .ok_or("a PEM header that is not `-----BEGIN <LABEL>-----`")?;
            let end = format!("-----END {label}-----");
            let stop = rest[at..]
                .find(&end)
                .ok_or_else(|| format!("a {label} without its END line"))?
                + at
                + end.len();
            let block = format!("{}\n", &rest[at..stop]);
            match label {
                "CERTIFICATE" => certificates.push(block),
                l if l.ends_with("PRIVATE KEY") => key = Some(block),
                other => {
                    return Err(format!(
                        "a {other}, where a certificate, its key and the fleet's authority were expected"
                    ))
                }
            }
            rest = &rest[stop..];
        }
        match (certificates.as_slice(), key) {
            ([certificate, authority], Some(key)) => Ok(Bundle {
                pair: Pair {
                    certificate: certificate.clone(),
                    key,
                },
                authority: authority.clone(),
            }),
            (_, key) => Err(format!(
                "{} certificate(s) and {} key: a role's certificate file holds its certificate, its private key and the fleet's authority (`tcpf credential DIR MISSION` makes them)",
                certificates.len(),
                if key.is_some() { "a" } else { "no" }
            )),
        }
    }

    /// The name of the bundle's holder (its certificate's Common Name).
    pub fn name(&self) -> Result<String> {
        common_name(self.pair.certificate.as_bytes())
    }
}

/// Names the holder, never the key: a bundle may end up in an error message.
impl std::fmt::Debug for Bundle {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self.name() {
            Ok(name) => write!(f, "the certificate of {name}"),
            Err(_) => f.write_str("a certificate without a name"),
        }
    }
}

/// The Common Name of the certificate in `pem`: the identity the router knows it by.
pub fn common_name(pem: &[u8]) -> Result<String> {
    let (_, pem) = x509_parser::pem::parse_x509_pem(pem).map_err(|e| failed!("not a PEM certificate: {e}"))?;
    let certificate = pem.parse_x509().map_err(|e| failed!("not an X.509 certificate: {e}"))?;
    let name = certificate
        .subject()
        .iter_common_name()
        .next()
        .ok_or_else(|| failed!("the certificate has no Common Name"))?;
    Ok(name
        .as_str()
        .map_err(|e| failed!("its Common Name is not text: {e}"))?
        .to_string())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::acl::Identity;

    #[test]
    fn each_certificate_is_named_after_its_role_and_signed_by_the_fleet() {
        let authority = Authority::new("b-current").unwrap();
        let agent = authority.issue(&Identity::Agent(2).to_string(), &[]).unwrap();
        assert_eq!(common_name(agent.certificate.as_bytes()).unwrap(), "agent-2");
        assert_eq!(common_name(authority.pem().as_bytes()).unwrap(), "tcpf fleet b-current");
        let (_, pem) = x509_parser::pem::parse_x509_pem(agent.certificate.as_bytes()).unwrap();
        let certificate = pem.parse_x509().unwrap();
        let (_, ca) = x509_parser::pem::parse_x509_pem(authority.pem().as_bytes()).unwrap();
        let ca = ca.parse_x509().unwrap();
        // That its signature holds is Zenoh's to check: tests/intruders.rs presents one of
        // another authority.
        assert_eq!(certificate.issuer(), ca.subject());
        assert!(ca.is_ca() && !certificate.is_ca());
        assert!(agent.key.contains("PRIVATE KEY"));
    }

    #[test]
    fn a_listening_role_names_where_it_listens() {
        let authority = Authority::new("fleet").unwrap();
        let world = authority
            .issue("world", &["127.0.0.1".into(), "shore.local".into()])
            .unwrap();
        let (_, pem) = x509_parser::pem::parse_x509_pem(world.certificate.as_bytes()).unwrap();
        let certificate = pem.parse_x509().unwrap();
        let names = format!(
            "{:?}",
            certificate
                .subject_alternative_name()
                .unwrap()
                .unwrap()
                .value
                .general_names
        );
        assert!(
            names.contains("127.0.0.1") || names.contains("[127, 0, 0, 1]"),
            "{names}"
        );
        assert!(names.contains("shore.local"), "{names}");
        assert!(common_name(b"not a certificate").is_err());
    }

    #[test]
    fn a_bundle_reads_back_and_says_what_it_lacks() {
        let authority = Authority::new("fleet").unwrap();
        let bundle = Bundle {
            pair: authority.issue("observer", &[]).unwrap(),
            authority: authority.pem(),
        };
        let again = Bundle::parse(&bundle.pem()).unwrap();
        assert_eq!(again.name().unwrap(), "observer");
        assert_eq!(again.authority, authority.pem());
        assert_eq!(again.pair.key, bundle.pair.key);
        let alone = Bundle::parse(&bundle.pair.certificate).unwrap_err();
        assert!(alone.starts_with("1 certificate(s) and no key"), "{alone}");
        let other = Bundle::parse("-----BEGIN PUBLIC KEY-----\nAA==\n-----END PUBLIC KEY-----\n").unwrap_err();
        assert!(other.starts_with("a PUBLIC KEY"), "{other}");
        // A header that lost a dash: the key's body is no label, and is never said.
        let torn = bundle
            .pem()
            .replacen("-----BEGIN PRIVATE KEY-----", "-----BEGIN PRIVATE KEY----", 1);
        let why = Bundle::parse(&torn).unwrap_err();
        assert!(
            why.starts_with("a PEM header that is not") && !why.contains("MI"),
            "{why}"
        );
        // An END before its BEGIN (a certificate that lost its head) is an error, not a panic.
        let headless = format!("-----END CERTIFICATE-----\n{}", bundle.pem());
        assert!(Bundle::parse(&headless).is_ok());
        let cut = bundle.pem().replacen("-----END CERTIFICATE-----", "", 1);
        assert!(Bundle::parse(&format!("-----END CERTIFICATE-----\n{cut}")).is_err());
    }
}
