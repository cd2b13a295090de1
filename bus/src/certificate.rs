//! A fleet's certificate authority and a certificate per role, for mutual TLS: the router knows
//! each link's role by its certificate's Common Name (`acl::Naming::CommonName`), which only the
//! fleet's authority can have signed. A stock ROS 2 (rmw_zenoh, whose Zenoh has TLS but no
//! user-password authentication) can present one.

use anyhow::{anyhow, Context, Result};
use base64::Engine;
use rcgen::{
    BasicConstraints, CertificateParams, CertifiedIssuer, DnType, ExtendedKeyUsagePurpose, IsCa, KeyPair,
    KeyUsagePurpose,
};

use serde_json::{json, Value};

use crate::acl::Identity;

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

    /// A certificate for `identity`, named after it. `hosts` are the names and addresses it may
    /// be reached at, when it listens: a client checks that the router it reaches is the one it
    /// meant, not only one of the fleet's.
    pub fn issue(&self, identity: Identity, hosts: &[String]) -> Result<Pair> {
        let mut params =
            CertificateParams::new(hosts.to_vec()).with_context(|| format!("{identity}: hosts {hosts:?}"))?;
        params.distinguished_name.push(DnType::CommonName, identity.to_string());
        params.key_usages = vec![KeyUsagePurpose::DigitalSignature];
        params.extended_key_usages = vec![ExtendedKeyUsagePurpose::ClientAuth, ExtendedKeyUsagePurpose::ServerAuth];
        let key = KeyPair::generate().with_context(|| format!("cannot make {identity}'s key"))?;
        let certificate = params
            .signed_by(&key, &self.issuer)
            .with_context(|| format!("cannot sign {identity}'s certificate"))?;
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

/// The Common Name of the certificate in `pem`: the identity the router knows it by.
pub fn common_name(pem: &[u8]) -> Result<String> {
    let (_, pem) = x509_parser::pem::parse_x509_pem(pem).map_err(|e| anyhow!("not a PEM certificate: {e}"))?;
    let certificate = pem.parse_x509().map_err(|e| anyhow!("not an X.509 certificate: {e}"))?;
    let name = certificate
        .subject()
        .iter_common_name()
        .next()
        .ok_or_else(|| anyhow!("the certificate has no Common Name"))?;
    Ok(name
        .as_str()
        .map_err(|e| anyhow!("its Common Name is not text: {e}"))?
        .to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_certificate_is_named_after_its_role_and_signed_by_the_fleet() {
        let authority = Authority::new("b-current").unwrap();
        let agent = authority.issue(Identity::Agent(2), &[]).unwrap();
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
            .issue(Identity::World, &["127.0.0.1".into(), "shore.local".into()])
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
}
