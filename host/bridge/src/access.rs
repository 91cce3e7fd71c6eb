//! Where a zenoh session listens and connects, and with which credentials: the session's
//! configuration ([`Access::config`]), as rmw_zenoh's own sessions are configured (peer mode,
//! no multicast scouting, timestamps on for the publication caches), TCP only.
//!
//! A robot served on an endpoint other machines can reach needs credentials (zenoh's user and
//! password authentication): [`Access::check_serving`]. Loopback needs none, as a process on
//! the same machine could reach the robot's serial port anyway.

use std::io::Write;
use std::path::{Path, PathBuf};

use crate::error::BridgeError;

/// A user and password every session of a served robot must present (zenoh's `usrpwd`
/// authentication, checked when a session opens its transport).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Credentials {
    /// The user name.
    pub user: String,
    /// The password.
    pub password: String,
}

impl Credentials {
    /// Credentials from a file whose first line is `user:password` (zenoh's dictionary format).
    pub fn from_file(path: impl AsRef<Path>) -> Result<Credentials, BridgeError> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path)
            .map_err(|e| BridgeError::Usage(format!("credentials file {}: {e}", path.display())))?;
        let line = text.lines().next().unwrap_or("");
        match line.split_once(':') {
            Some((user, password)) if !user.is_empty() && !password.is_empty() => Ok(Credentials {
                user: user.to_string(),
                password: password.to_string(),
            }),
            _ => Err(BridgeError::Usage(format!(
                "credentials file {}: its first line is not `user:password`",
                path.display()
            ))),
        }
    }
}

/// A zenoh session's endpoints and credentials.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Access {
    /// Endpoints it listens on, e.g. `tcp/127.0.0.1:7447` (none: it only connects).
    pub listen: Vec<String>,
    /// Endpoints it connects to, e.g. a served robot's or an rmw_zenoh router's
    /// `tcp/localhost:7447`.
    pub connect: Vec<String>,
    /// The user and password it presents, and that sessions connecting to it must present.
    pub credentials: Option<Credentials>,
}

/// Whether `endpoint` (`tcp/<host>:<port>`) can be reached from this machine only.
pub fn is_loopback(endpoint: &str) -> bool {
    let Some(addr) = endpoint.strip_prefix("tcp/") else {
        return false;
    };
    let host = match addr.rsplit_once(':') {
        Some((host, _)) => host,
        None => addr,
    };
    let host = host.trim_start_matches('[').trim_end_matches(']');
    host == "localhost"
        || host
            .parse::<std::net::IpAddr>()
            .is_ok_and(|ip| ip.is_loopback())
}

fn tcp_only(endpoints: &[String]) -> Result<(), BridgeError> {
    match endpoints.iter().find(|e| !e.starts_with("tcp/")) {
        Some(e) => Err(BridgeError::Usage(format!(
            "endpoint {e:?}: this build speaks TCP only (`tcp/<host>:<port>`), as rmw_zenoh does"
        ))),
        None => Ok(()),
    }
}

impl Access {
    /// Listening on `endpoint` only.
    pub fn listen(endpoint: impl Into<String>) -> Access {
        Access {
            listen: vec![endpoint.into()],
            ..Access::default()
        }
    }

    /// Connecting to `endpoint` only.
    pub fn connect(endpoint: impl Into<String>) -> Access {
        Access {
            connect: vec![endpoint.into()],
            ..Access::default()
        }
    }

    /// With `credentials`.
    pub fn with_credentials(mut self, credentials: Credentials) -> Access {
        self.credentials = Some(credentials);
        self
    }

    /// A robot may be served here: every endpoint it listens on is loopback, or it has
    /// credentials ([`BridgeError::Unauthenticated`] otherwise).
    pub fn check_serving(&self) -> Result<(), BridgeError> {
        if self.credentials.is_some() {
            return Ok(());
        }
        match self.listen.iter().find(|e| !is_loopback(e)) {
            Some(e) => Err(BridgeError::Unauthenticated {
                endpoint: e.clone(),
            }),
            None => Ok(()),
        }
    }

    /// The session's configuration. With credentials, a session connecting to this one is
    /// checked against them: they are written, readable by this user only, to a dictionary
    /// file in `dir`, which must outlive the session's start.
    pub fn config(&self, dir: &Path) -> Result<zenoh::Config, BridgeError> {
        tcp_only(&self.listen)?;
        tcp_only(&self.connect)?;
        let mut c = zenoh::Config::default();
        let mut set = |key: &str, value: String| {
            c.insert_json5(key, &value)
                .map_err(|e| BridgeError::zenoh(format!("setting {key}"), e))
        };
        set("mode", "\"peer\"".into())?;
        set("listen/endpoints", json_list(&self.listen))?;
        set("connect/endpoints", json_list(&self.connect))?;
        set("scouting/multicast/enabled", "false".into())?;
        set(
            "timestamping/enabled",
            "{ router: true, peer: true, client: true }".into(),
        )?;
        if let Some(cr) = &self.credentials {
            let dictionary = write_dictionary(dir, cr)?;
            set("transport/auth/usrpwd/user", json_string(&cr.user))?;
            set("transport/auth/usrpwd/password", json_string(&cr.password))?;
            set(
                "transport/auth/usrpwd/dictionary_file",
                json_string(&dictionary.to_string_lossy()),
            )?;
        }
        Ok(c)
    }
}

fn json_string(s: &str) -> String {
    format!("{s:?}")
}

fn json_list(items: &[String]) -> String {
    let quoted: Vec<String> = items.iter().map(|s| json_string(s)).collect();
    format!("[{}]", quoted.join(", "))
}

/// `dir/usrpwd`, holding `user:password`, readable by this user only.
fn write_dictionary(dir: &Path, cr: &Credentials) -> Result<PathBuf, BridgeError> {
    use std::os::unix::fs::OpenOptionsExt;
    let path = dir.join("usrpwd");
    let io = |e: std::io::Error| BridgeError::Usage(format!("{}: {e}", path.display()));
    std::fs::create_dir_all(dir).map_err(io)?;
    let mut f = std::fs::OpenOptions::new()
        .write(true)
        .create(true)
        .truncate(true)
        .mode(0o600)
        .open(&path)
        .map_err(io)?;
    writeln!(f, "{}:{}", cr.user, cr.password).map_err(io)?;
    Ok(path)
}

/// Opens a zenoh session with `access`; its dictionary file, if any, in a directory of this
/// process's own.
pub fn open(access: &Access) -> Result<zenoh::Session, BridgeError> {
    use zenoh::Wait;
    static SESSIONS: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let n = SESSIONS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let dir = std::env::temp_dir().join(format!("ferrobot-zenoh-{}-{n}", std::process::id()));
    let config = access.config(&dir)?;
    let session = zenoh::open(config)
        .wait()
        .map_err(|e| BridgeError::zenoh("opening a session", e));
    let _ = std::fs::remove_dir_all(&dir);
    session
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn loopback_is_told_from_the_rest() {
        for e in [
            "tcp/127.0.0.1:7447",
            "tcp/localhost:0",
            "tcp/[::1]:7447",
            "tcp/127.3.2.1:1",
        ] {
            assert!(is_loopback(e), "{e}");
        }
        for e in [
            "tcp/0.0.0.0:7447",
            "tcp/[::]:7447",
            "tcp/192.168.1.5:7447",
            "udp/127.0.0.1:1",
        ] {
            assert!(!is_loopback(e), "{e}");
        }
    }

    #[test]
    fn serving_beyond_loopback_needs_credentials() {
        let open = Access::listen("tcp/0.0.0.0:7447");
        assert!(matches!(
            open.check_serving(),
            Err(BridgeError::Unauthenticated { .. })
        ));
        let cr = Credentials {
            user: "lab".into(),
            password: "s3cret".into(),
        };
        assert!(open.with_credentials(cr).check_serving().is_ok());
        assert!(Access::listen("tcp/127.0.0.1:7447").check_serving().is_ok());
    }
}
