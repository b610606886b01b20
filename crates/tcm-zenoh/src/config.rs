//! Zenoh configurations for one machine (docs/distributed.md, "Configuration"): peer mode,
//! multicast scouting off, and every socket on 127.0.0.1, so nothing leaves the host. The
//! executive listens on one port; agents connect to it and listen nowhere. With a system's
//! certificates ([`Certs`]), the same over TLS with mutual authentication: only a process holding
//! a certificate of the system's authority opens a link ("Who may speak").

use crate::Error;
use std::path::PathBuf;
use std::time::Duration;

/// One process's credentials in a system (PEM files): the certificate of the system's authority,
/// which every peer's certificate must be signed by, and this process's certificate (signed by
/// it, naming the address it is reached at, `IP:127.0.0.1` on one machine) and private key.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Certs {
    /// The authority's certificate.
    pub authority: PathBuf,
    /// This process's certificate.
    pub certificate: PathBuf,
    /// This process's private key.
    pub key: PathBuf,
}

/// `c` with mutual TLS: its `tls/…` endpoints present `certs`' certificate, both when listening
/// and when connecting, and accept only a peer whose certificate the system's authority signed
/// (and, connecting, one that names the address connected to). A `tcp/…` endpoint of `c` is not
/// protected: use TLS endpoints only ([`tls_endpoint`]).
pub fn with_mtls(mut c: zenoh::Config, certs: &Certs) -> Result<zenoh::Config, Error> {
    let path = |p: &PathBuf| serde_json::to_string(&p.to_string_lossy()).unwrap_or_default();
    let tls = "transport/link/tls";
    set(
        &mut c,
        &format!("{tls}/root_ca_certificate"),
        &path(&certs.authority),
    )?;
    set(
        &mut c,
        &format!("{tls}/listen_certificate"),
        &path(&certs.certificate),
    )?;
    set(
        &mut c,
        &format!("{tls}/listen_private_key"),
        &path(&certs.key),
    )?;
    set(
        &mut c,
        &format!("{tls}/connect_certificate"),
        &path(&certs.certificate),
    )?;
    set(
        &mut c,
        &format!("{tls}/connect_private_key"),
        &path(&certs.key),
    )?;
    set(&mut c, &format!("{tls}/enable_mtls"), "true")?;
    set(&mut c, &format!("{tls}/verify_name_on_connect"), "true")?;
    Ok(c)
}

/// Who may be in a system, by the common names of their certificates: its executives, its
/// agents (an agent's common name is its agent name) and the clients of its serving executives
/// (`tdl load`, `tdl start`, …; a client's common name is its client name).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Roster {
    /// The executives' common names.
    pub executives: Vec<String>,
    /// The agents' common names, which are their names.
    pub agents: Vec<String>,
    /// The clients' common names, which are their names: the only members that may send a
    /// serving executive requests (`tdl/<system>/serve/**`), each under its own name only.
    pub clients: Vec<String>,
}

/// `c` with zenoh's access control for `system` (docs/distributed.md, "Who may speak"), for use
/// with mutual TLS ([`with_mtls`]): what this process receives from a peer is checked against the
/// common name of the peer's certificate. A peer named in `roster` may send anything except what
/// speaks for another: an agent may not publish on another agent's inbox keys
/// (`tdl/<system>/to-exec/*/<other>`), nor on any agent's (`tdl/<system>/to-agent/**`), nor hold
/// an executive's token or another agent's; an executive may not publish on `to-exec` keys nor
/// hold an agent's tokens. Only a client may query a serving executive
/// (`tdl/<system>/serve/<executive>/<client>`), and under its own name only; a client may not
/// publish nor hold tokens in the system. A peer that `roster` does not name is refused
/// everything.
pub fn with_access(
    mut c: zenoh::Config,
    system: &str,
    roster: &Roster,
) -> Result<zenoh::Config, Error> {
    let all = [
        "put",
        "delete",
        "declare_subscriber",
        "query",
        "reply",
        "declare_queryable",
        "liveliness_token",
        "declare_liveliness_subscriber",
        "liveliness_query",
    ];
    let mut rules = vec![serde_json::json!({
        "id": "members",
        "messages": all,
        "flows": ["ingress", "egress"],
        "permission": "allow",
        "key_exprs": ["**"],
    })];
    let mut subjects = Vec::new();
    let mut policies = Vec::new();
    let deny = |id: String, messages: &[&str], keys: Vec<String>| {
        serde_json::json!({
            "id": id,
            "messages": messages,
            "flows": ["ingress"],
            "permission": "deny",
            "key_exprs": keys,
        })
    };
    for (i, agent) in roster.agents.iter().enumerate() {
        let others: Vec<&String> = roster.agents.iter().filter(|a| *a != agent).collect();
        let mut puts = vec![format!("tdl/{system}/to-agent/**")];
        puts.extend(others.iter().map(|o| format!("tdl/{system}/to-exec/*/{o}")));
        let mut tokens = vec![format!("tdl/{system}/executives/*")];
        for o in &others {
            tokens.push(format!("tdl/{system}/agents/{o}"));
            tokens.push(format!("tdl/{system}/offers/*/{o}"));
        }
        rules.push(deny(format!("agent-{i}-puts"), &["put", "delete"], puts));
        rules.push(deny(
            format!("agent-{i}-tokens"),
            &["liveliness_token"],
            tokens,
        ));
        subjects
            .push(serde_json::json!({"id": format!("agent-{i}"), "cert_common_names": [agent]}));
        policies.push(serde_json::json!({
            "rules": ["members", format!("agent-{i}-puts"), format!("agent-{i}-tokens"), "no-serve"],
            "subjects": [format!("agent-{i}")],
        }));
    }
    // Requests to serving executives: from clients only.
    rules.push(deny(
        "no-serve".into(),
        &["query"],
        vec![format!("tdl/{system}/serve/**")],
    ));
    for (i, client) in roster.clients.iter().enumerate() {
        // Under its own name only: every other name of the roster is denied to it (a name the
        // roster does not hold is refused by the executive's own list of clients).
        let others: Vec<String> = roster
            .executives
            .iter()
            .chain(&roster.agents)
            .chain(&roster.clients)
            .filter(|o| *o != client)
            .map(|o| format!("tdl/{system}/serve/*/{o}"))
            .collect();
        let mut own = vec![
            serde_json::json!("members"),
            serde_json::json!(format!("client-{i}-writes")),
        ];
        if !others.is_empty() {
            rules.push(deny(format!("client-{i}-names"), &["query"], others));
            own.push(serde_json::json!(format!("client-{i}-names")));
        }
        rules.push(deny(
            format!("client-{i}-writes"),
            &["put", "delete", "liveliness_token", "declare_queryable"],
            vec![format!("tdl/{system}/**")],
        ));
        subjects
            .push(serde_json::json!({"id": format!("client-{i}"), "cert_common_names": [client]}));
        policies.push(serde_json::json!({
            "rules": own,
            "subjects": [format!("client-{i}")],
        }));
    }
    if !roster.executives.is_empty() {
        rules.push(deny(
            "executive-puts".into(),
            &["put", "delete"],
            vec![format!("tdl/{system}/to-exec/**")],
        ));
        rules.push(deny(
            "executive-tokens".into(),
            &["liveliness_token"],
            vec![
                format!("tdl/{system}/agents/*"),
                format!("tdl/{system}/offers/**"),
            ],
        ));
        subjects.push(serde_json::json!({
            "id": "executives",
            "cert_common_names": roster.executives,
        }));
        policies.push(serde_json::json!({
            "rules": ["members", "executive-puts", "executive-tokens", "no-serve"],
            "subjects": ["executives"],
        }));
    }
    let acl = serde_json::json!({
        "enabled": true,
        "default_permission": "deny",
        "rules": rules,
        "subjects": subjects,
        "policies": policies,
    });
    set(&mut c, "access_control", &acl.to_string())?;
    Ok(c)
}

/// `tls/127.0.0.1:port`.
pub fn tls_endpoint(port: u16) -> String {
    format!("tls/127.0.0.1:{port}")
}

/// The configuration of an executive on this machine with mutual TLS: listening on
/// `tls/127.0.0.1:port` only.
pub fn loopback_tls_listen(port: u16, certs: &Certs) -> Result<zenoh::Config, Error> {
    with_mtls(peer(&[tls_endpoint(port)], &[])?, certs)
}

/// The configuration of an agent on this machine with mutual TLS: connecting to the executive's
/// `tls/127.0.0.1:port`, listening nowhere.
pub fn loopback_tls_connect(port: u16, certs: &Certs) -> Result<zenoh::Config, Error> {
    with_mtls(peer(&[], &[tls_endpoint(port)])?, certs)
}

/// A zenoh configuration: peer mode, multicast scouting off, listening on `listen` and
/// connecting to `connect` (endpoints such as `tcp/127.0.0.1:7447`).
pub fn peer(listen: &[String], connect: &[String]) -> Result<zenoh::Config, Error> {
    let mut c = zenoh::Config::default();
    set(&mut c, "mode", r#""peer""#)?;
    set(&mut c, "scouting/multicast/enabled", "false")?;
    set(&mut c, "listen/endpoints", &json_list(listen))?;
    set(&mut c, "connect/endpoints", &json_list(connect))?;
    Ok(c)
}

/// The configuration of an executive on this machine: listening on `tcp/127.0.0.1:port` only.
pub fn loopback_listen(port: u16) -> Result<zenoh::Config, Error> {
    peer(&[endpoint(port)], &[])
}

/// The configuration of an agent on this machine: connecting to the executive's
/// `tcp/127.0.0.1:port`, listening nowhere.
pub fn loopback_connect(port: u16) -> Result<zenoh::Config, Error> {
    peer(&[], &[endpoint(port)])
}

/// `tcp/127.0.0.1:port`.
pub fn endpoint(port: u16) -> String {
    format!("tcp/127.0.0.1:{port}")
}

/// Sets the lease of the config's links: how long a silent link (no message, no keep-alive) lives
/// before zenoh closes it, and so how long a broken link takes to surface as agent loss (zenoh's
/// default: 10 s; a process that dies closes its sockets, which is seen at once).
pub fn with_lease(mut c: zenoh::Config, lease: Duration) -> Result<zenoh::Config, Error> {
    let ms = lease.as_millis().max(1);
    set(&mut c, "transport/link/tx/lease", &ms.to_string())?;
    Ok(c)
}

/// A TCP port on 127.0.0.1 free now (the system picks it), for an executive to listen on. Another
/// process may take it before the executive does; [`crate::Executive::open_loopback`] tries again
/// with another.
pub fn free_port() -> Result<u16, Error> {
    let l = std::net::TcpListener::bind("127.0.0.1:0")
        .map_err(|e| Error::Zenoh(format!("no free port on 127.0.0.1: {e}")))?;
    l.local_addr()
        .map(|a| a.port())
        .map_err(|e| Error::Zenoh(format!("no free port on 127.0.0.1: {e}")))
}

fn json_list(items: &[String]) -> String {
    serde_json::to_string(items).unwrap_or_else(|_| "[]".into())
}

fn set(c: &mut zenoh::Config, key: &str, value: &str) -> Result<(), Error> {
    c.insert_json5(key, value)
        .map_err(|e| Error::Zenoh(format!("config {key} = {value}: {e}")))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn loopback_configs_pin_every_socket_to_127_0_0_1() {
        let c = loopback_listen(7447).expect("config");
        let text = format!("{c}");
        assert!(text.contains("tcp/127.0.0.1:7447"), "{text}");
        assert!(with_lease(c, Duration::from_millis(1500)).is_ok());
        assert!(loopback_connect(7447).is_ok());
    }

    #[test]
    fn a_tls_config_names_the_certificates_and_asks_for_the_peers() {
        let certs = Certs {
            authority: "/c/ca.pem".into(),
            certificate: "/c/me.pem".into(),
            key: "/c/me.key".into(),
        };
        let text = format!("{}", loopback_tls_listen(7447, &certs).expect("config"));
        for part in ["tls/127.0.0.1:7447", "/c/ca.pem", "/c/me.pem", "/c/me.key"] {
            assert!(text.contains(part), "{part}: {text}");
        }
        assert!(loopback_tls_connect(7447, &certs).is_ok());
    }
}
