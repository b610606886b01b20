//! Zenoh configurations for one machine (docs/distributed.md, "Configuration"): peer mode,
//! multicast scouting off, and every socket on 127.0.0.1, so nothing leaves the host. The
//! executive listens on one port; agents connect to it and listen nowhere.

use crate::Error;
use std::time::Duration;

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
}
