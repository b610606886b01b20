//! `tdl certs`: the files are written with the names `tcm_zenoh::config::Certs` is given
//! (docs/distributed.md, "Mutual TLS"), keys readable by their owner only; each member's
//! certificate is signed by the system's authority (checked by parsing them back with
//! `x509-parser` and verifying the signatures, and with `openssl verify` when it is on PATH), names
//! the member and its addresses, and is for both ends of a link; nothing is overwritten without
//! `--force`.

use std::path::{Path, PathBuf};

use x509_parser::extensions::GeneralName;
use x509_parser::prelude::{FromDer, X509Certificate};

use super::tdl;

/// A fresh directory for one test's files.
fn work_dir(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("tdl-certs-{name}"));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

/// The DER of the one certificate in a PEM file.
fn der(path: &Path) -> Vec<u8> {
    let text = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let (_, pem) = x509_parser::pem::parse_x509_pem(&text).expect("a PEM certificate");
    assert_eq!(pem.label, "CERTIFICATE");
    pem.contents
}

fn common_name(cert: &X509Certificate<'_>) -> String {
    let cn = cert.subject().iter_common_name().next().expect("a CN");
    cn.as_str().expect("a string").to_owned()
}

#[test]
fn certs_are_signed_by_the_systems_authority_and_not_overwritten() {
    let dir = work_dir("robot");
    let out_dir = dir.display().to_string();
    let (code, out, err) = tdl(&[
        "certs",
        "--system",
        "robot",
        "--out",
        &out_dir,
        "--days",
        "30",
        "exec",
        "arm",
        "voice@10.0.0.1,robot.local",
    ]);
    assert_eq!(code, 0, "{out}{err}");
    for name in ["authority", "exec", "arm", "voice"] {
        assert!(
            out.contains(&format!("{}/{name}.pem", dir.display())),
            "{out}"
        );
        assert!(dir.join(format!("{name}.key")).is_file());
    }
    assert!(out.contains("tcm_zenoh::config::with_mtls("), "{out}");

    // The keys are PKCS#8 PEM, for the owner only.
    for name in ["authority", "exec", "arm", "voice"] {
        let key = dir.join(format!("{name}.key"));
        let text = std::fs::read_to_string(&key).expect("the key");
        assert!(text.starts_with("-----BEGIN PRIVATE KEY-----\n"), "{text}");
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt as _;
            let mode = std::fs::metadata(&key)
                .expect("metadata")
                .permissions()
                .mode();
            assert_eq!(mode & 0o777, 0o600, "{}", key.display());
        }
    }

    let authority_der = der(&dir.join("authority.pem"));
    let (_, authority) = X509Certificate::from_der(&authority_der).expect("the authority parses");
    assert!(authority.is_ca());
    assert_eq!(common_name(&authority), "robot authority");
    // Self-signed.
    authority
        .verify_signature(None)
        .expect("the authority signed itself");
    let other_der = {
        let other = work_dir("other");
        let (code, out, err) = tdl(&[
            "certs",
            "--system",
            "robot",
            "--out",
            &other.display().to_string(),
            "arm",
        ]);
        assert_eq!(code, 0, "{out}{err}");
        der(&other.join("authority.pem"))
    };
    let (_, other) = X509Certificate::from_der(&other_der).expect("parses");

    let addresses = |cert: &X509Certificate<'_>| -> Vec<String> {
        let san = cert
            .subject_alternative_name()
            .expect("one SAN extension")
            .expect("a SAN");
        san.value
            .general_names
            .iter()
            .map(|n| match n {
                GeneralName::DNSName(d) => (*d).to_owned(),
                GeneralName::IPAddress(ip) => {
                    ip.iter().map(u8::to_string).collect::<Vec<_>>().join(".")
                }
                other => format!("{other:?}"),
            })
            .collect()
    };
    for (name, reached) in [
        ("exec", ["127.0.0.1", "localhost"]),
        ("arm", ["127.0.0.1", "localhost"]),
        ("voice", ["10.0.0.1", "robot.local"]),
    ] {
        let bytes = der(&dir.join(format!("{name}.pem")));
        let (_, cert) = X509Certificate::from_der(&bytes).expect("parses");
        assert_eq!(common_name(&cert), name);
        assert!(!cert.is_ca(), "{name}");
        assert_eq!(cert.issuer(), authority.subject(), "{name}");
        cert.verify_signature(Some(authority.public_key()))
            .unwrap_or_else(|e| panic!("{name} is not signed by the authority: {e}"));
        // Another run's authority (same system name, other key) did not sign it.
        assert!(
            cert.verify_signature(Some(other.public_key())).is_err(),
            "{name}"
        );
        assert_eq!(addresses(&cert), reached, "{name}");
        let usage = cert
            .extended_key_usage()
            .expect("one EKU")
            .expect("an EKU")
            .value;
        assert!(usage.server_auth && usage.client_auth, "{name}");
        let days = (cert.validity().not_after - cert.validity().not_before)
            .expect("a duration")
            .whole_hours();
        assert_eq!(days, 30 * 24 + 1, "{name}: an hour back, 30 days on");
        assert!(cert.validity().is_valid(), "{name}");
    }

    // openssl, an independent verifier, agrees (when it is there).
    match std::process::Command::new("openssl")
        .args([
            "verify",
            "-CAfile",
            "authority.pem",
            "-purpose",
            "sslserver",
        ])
        .args(["exec.pem", "arm.pem", "voice.pem"])
        .current_dir(&dir)
        .output()
    {
        Ok(verified) => {
            let said = String::from_utf8_lossy(&verified.stdout);
            assert!(
                verified.status.success(),
                "{said}{}",
                String::from_utf8_lossy(&verified.stderr)
            );
            assert_eq!(said, "exec.pem: OK\narm.pem: OK\nvoice.pem: OK\n");
        }
        Err(e) => eprintln!("openssl verify skipped: cannot run openssl ({e})"),
    }

    // Again: nothing is replaced, not even the files that do not exist yet, and the error names
    // what exists.
    let before = std::fs::read(dir.join("arm.pem")).expect("arm.pem");
    let (code, out, err) = tdl(&[
        "certs", "--system", "robot", "--out", &out_dir, "arm", "leg",
    ]);
    assert_eq!(code, 2, "{out}{err}");
    assert!(err.contains("not overwriting"), "{err}");
    assert!(
        err.contains("arm.pem") && err.contains("authority.key"),
        "{err}"
    );
    assert!(!dir.join("leg.pem").exists() && !dir.join("leg.key").exists());
    assert_eq!(std::fs::read(dir.join("arm.pem")).expect("arm.pem"), before);

    // With --force it is: a new authority, and the key is still the owner's only.
    let (code, out, err) = tdl(&[
        "certs", "--system", "robot", "--out", &out_dir, "--force", "arm", "leg",
    ]);
    assert_eq!(code, 0, "{out}{err}");
    assert_ne!(std::fs::read(dir.join("arm.pem")).expect("arm.pem"), before);
    assert_ne!(der(&dir.join("authority.pem")), authority_der);
    assert!(dir.join("leg.key").is_file());
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt as _;
        let mode = std::fs::metadata(dir.join("arm.key"))
            .expect("metadata")
            .permissions()
            .mode();
        assert_eq!(mode & 0o777, 0o600);
    }
}

#[test]
fn certs_refuses_bad_members() {
    let dir = work_dir("bad");
    let out_dir = dir.display().to_string();
    for (members, says) in [
        (&["a/b"][..], "a name is letters"),
        (&["authority"][..], "names the authority's files"),
        (&["arm", "arm"][..], "named twice"),
        (&["arm@"][..], "an empty address"),
        (&["arm@not an address"][..], "is not an address"),
    ] {
        let mut args = vec!["certs", "--system", "robot", "--out", &out_dir];
        args.extend_from_slice(members);
        let (code, out, err) = tdl(&args);
        assert_eq!(code, 2, "{members:?}: {out}{err}");
        assert!(err.contains(says), "{members:?}: {err}");
    }
    // Nothing was written for them.
    assert!(!dir.exists());
    // No member, or no validity, is a usage error.
    assert_eq!(tdl(&["certs", "--system", "robot", "--out", &out_dir]).0, 2);
    let (code, _, _) = tdl(&[
        "certs", "--system", "robot", "--out", &out_dir, "--days", "0", "arm",
    ]);
    assert_eq!(code, 2);
}
