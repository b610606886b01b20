//! `tdl certs`: a system's certificates for mutual TLS (docs/distributed.md, "Mutual TLS").
//!
//! An authority for the system (`authority.pem`, its key `authority.key`), and for each member
//! (an executive, an agent, a client: the common name its roster uses) a certificate signed by it
//! and its key, `<member>.pem` and `<member>.key`: the three files `tcm_zenoh::config::Certs`
//! names. Keys are ECDSA P-256 in PKCS#8 PEM, made with `rcgen` (on `ring`). A member's
//! certificate names the addresses it is reached at (`exec@10.0.0.1,robot.local`; 127.0.0.1 and
//! `localhost` when none is given), which a peer connecting to it checks, and may be used both to
//! serve and to connect. Every file is checked before any is written: an existing one stops the
//! command, unless `--force`; keys are written with mode 0600 on Unix.

use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::{Context as _, bail};
use rcgen::{
    BasicConstraints, CertificateParams, DnType, ExtendedKeyUsagePurpose, IsCa, Issuer, KeyPair,
    KeyUsagePurpose,
};

/// `tdl certs`'s arguments.
#[derive(clap::Args)]
pub(crate) struct Args {
    /// The system's name (the authority's common name is `<NAME> authority`).
    #[arg(long, value_name = "NAME")]
    system: String,
    /// The directory to write into (created if needed).
    #[arg(long, value_name = "DIR")]
    out: PathBuf,
    /// How many days the certificates are valid for, from now.
    #[arg(long, value_name = "N", default_value_t = 365,
          value_parser = clap::value_parser!(u32).range(1..=36500))]
    days: u32,
    /// Replace files that exist already.
    #[arg(long)]
    force: bool,
    /// The members: each a common name (as the roster names it: an executive, an agent, a
    /// client), optionally with the addresses it is reached at, `NAME@ADDR[,ADDR...]` (IP
    /// addresses or DNS names; default 127.0.0.1 and localhost).
    #[arg(required = true, value_name = "MEMBER")]
    members: Vec<String>,
}

/// A member to make a certificate for.
struct Member {
    name: String,
    addresses: Vec<String>,
}

/// The name of the authority's files in the output directory.
const AUTHORITY: &str = "authority";

/// Parses `NAME[@ADDR,...]`.
fn member(arg: &str) -> anyhow::Result<Member> {
    let (name, addresses) = match arg.split_once('@') {
        Some((name, list)) => {
            let addresses: Vec<String> = list.split(',').map(str::to_owned).collect();
            if addresses.iter().any(String::is_empty) {
                bail!("member `{arg}`: an empty address (write `NAME@ADDR,ADDR`)");
            }
            let host = |a: &str| {
                a.chars()
                    .all(|c| c.is_ascii_alphanumeric() || matches!(c, '-' | '.'))
                    && !a.starts_with(['-', '.'])
            };
            if let Some(bad) = addresses
                .iter()
                .find(|a| a.parse::<std::net::IpAddr>().is_err() && !host(a))
            {
                bail!("member `{arg}`: `{bad}` is not an address (an IP address or a DNS name)");
            }
            (name, addresses)
        }
        None => (arg, vec!["127.0.0.1".to_owned(), "localhost".to_owned()]),
    };
    let fine = |c: char| c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.');
    if name.is_empty() || name.starts_with('.') || !name.chars().all(fine) {
        bail!(
            "member `{arg}`: a name is letters, digits, `-`, `_` and `.` (not first): it is a \
             common name, a file name and a part of zenoh keys"
        );
    }
    if name == AUTHORITY {
        bail!("member `{arg}`: `{AUTHORITY}` names the authority's files");
    }
    Ok(Member {
        name: name.to_owned(),
        addresses,
    })
}

/// Makes the certificates, writes them and says what it wrote on `out`.
pub(crate) fn run(args: Args, out: &mut impl Write) -> anyhow::Result<u8> {
    let members = args
        .members
        .iter()
        .map(|m| member(m))
        .collect::<anyhow::Result<Vec<_>>>()?;
    for (i, m) in members.iter().enumerate() {
        if members[..i].iter().any(|o| o.name == m.name) {
            bail!("member `{}` is named twice", m.name);
        }
    }
    if args.system.trim().is_empty() {
        bail!("--system: the system's name is empty");
    }
    let dir = &args.out;
    let names: Vec<&str> = std::iter::once(AUTHORITY)
        .chain(members.iter().map(|m| m.name.as_str()))
        .collect();
    let paths = |name: &str| {
        (
            dir.join(format!("{name}.pem")),
            dir.join(format!("{name}.key")),
        )
    };
    if !args.force {
        let existing: Vec<String> = names
            .iter()
            .flat_map(|n| {
                let (pem, key) = paths(n);
                [pem, key]
            })
            .filter(|p| p.exists())
            .map(|p| p.display().to_string())
            .collect();
        if !existing.is_empty() {
            bail!(
                "not overwriting {} (use --force to replace)",
                existing.join(", ")
            );
        }
    }

    let now = time::OffsetDateTime::now_utc();
    // An hour back, for clocks a little behind this one.
    let not_before = now - time::Duration::hours(1);
    let not_after = now + time::Duration::days(i64::from(args.days));

    let authority_key = KeyPair::generate().context("cannot make the authority's key")?;
    let mut params = CertificateParams::default();
    params.distinguished_name = rcgen::DistinguishedName::new();
    params
        .distinguished_name
        .push(DnType::CommonName, format!("{} authority", args.system));
    params
        .distinguished_name
        .push(DnType::OrganizationName, args.system.as_str());
    params.is_ca = IsCa::Ca(BasicConstraints::Constrained(0));
    params.key_usages = vec![
        KeyUsagePurpose::KeyCertSign,
        KeyUsagePurpose::CrlSign,
        KeyUsagePurpose::DigitalSignature,
    ];
    params.not_before = not_before;
    params.not_after = not_after;
    let authority = params
        .self_signed(&authority_key)
        .context("cannot make the authority's certificate")?;
    let issuer = Issuer::new(params, authority_key);

    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let (pem, key) = paths(AUTHORITY);
    write(&pem, &authority.pem(), false, args.force)?;
    write(&key, &issuer.key().serialize_pem(), true, args.force)?;
    writeln!(
        out,
        "wrote {} (the authority of system `{}`: every member gets a copy)",
        pem.display(),
        args.system
    )?;
    writeln!(
        out,
        "wrote {} (the authority's key: keep it secret and off the robots)",
        key.display()
    )?;

    for m in &members {
        let member_key = KeyPair::generate().context("cannot make a key")?;
        let mut params = CertificateParams::new(m.addresses.clone())
            .with_context(|| format!("member `{}`: an address is not valid", m.name))?;
        params.distinguished_name = rcgen::DistinguishedName::new();
        params
            .distinguished_name
            .push(DnType::CommonName, m.name.as_str());
        params
            .distinguished_name
            .push(DnType::OrganizationName, args.system.as_str());
        params.is_ca = IsCa::ExplicitNoCa;
        params.key_usages = vec![KeyUsagePurpose::DigitalSignature];
        params.extended_key_usages = vec![
            ExtendedKeyUsagePurpose::ServerAuth,
            ExtendedKeyUsagePurpose::ClientAuth,
        ];
        params.use_authority_key_identifier_extension = true;
        params.not_before = not_before;
        params.not_after = not_after;
        let cert = params
            .signed_by(&member_key, &issuer)
            .with_context(|| format!("cannot make the certificate of `{}`", m.name))?;
        let (pem, key) = paths(&m.name);
        write(&pem, &cert.pem(), false, args.force)?;
        write(&key, &member_key.serialize_pem(), true, args.force)?;
        writeln!(
            out,
            "wrote {} and {} (`{}`, reached at {})",
            pem.display(),
            key.display(),
            m.name,
            m.addresses.join(", ")
        )?;
    }
    writeln!(
        out,
        "valid for {} days; use (Rust): tcm_zenoh::config::with_mtls(config, &Certs {{ \
         authority: \"{dir}/authority.pem\".into(), certificate: \"{dir}/<member>.pem\".into(), \
         key: \"{dir}/<member>.key\".into() }})",
        args.days,
        dir = dir.display()
    )?;
    Ok(0)
}

/// Writes `text` to `path`, a new file (an existing one is removed first when `force`); a key
/// readable by its owner only on Unix.
fn write(path: &Path, text: &str, secret: bool, force: bool) -> anyhow::Result<()> {
    if force {
        match std::fs::remove_file(path) {
            Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
                return Err(e).with_context(|| format!("cannot replace {}", path.display()));
            }
            _ => {}
        }
    }
    let mut options = std::fs::OpenOptions::new();
    options.write(true).create_new(true);
    #[cfg(unix)]
    {
        use std::os::unix::fs::OpenOptionsExt as _;
        options.mode(if secret { 0o600 } else { 0o644 });
    }
    #[cfg(not(unix))]
    let _ = secret;
    let mut file = options
        .open(path)
        .with_context(|| format!("cannot create {}", path.display()))?;
    file.write_all(text.as_bytes())
        .with_context(|| format!("cannot write {}", path.display()))
}
