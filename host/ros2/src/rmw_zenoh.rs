//! The names rmw_zenoh (ROS 2's zenoh middleware, Jazzy 0.2.4 and later) gives things on
//! zenoh, so that a ROS 2 node sees a Ferrobot topic as one of its own:
//!
//! - a topic's data under `<domain>/<name>/<pkg>::msg::dds_::<Type>_/<RIHS01 hash>`
//!   ([`topic_key`]);
//! - every node and entity announced by a liveliness token under `@ros2_lv/...`
//!   ([`Node::token`], [`Node::entity_token`]), with `/` written `%` in names and the QoS in
//!   rmw_zenoh's compact form ([`Qos::to_keyexpr`]);
//! - each entity's GID, XXH3-128 of its token ([`gid`]);
//! - on every sample, a 33-byte attachment: sequence number, source time, GID
//!   ([`Attachment`]); a ROS 2 subscriber drops a sample without it.
//!
//! Payloads are CDR ([`crate::cdr`]) with no zenoh encoding set. Services are not here yet.
//! Every layout here, with the rmw_zenoh source it was read from: `docs/design/rmw-zenoh.md`.

use crate::schemas::MsgType;
use crate::type_hash::{rihs01, TypeHashError};

/// The first chunk of every liveliness token.
pub const ADMIN_SPACE: &str = "@ros2_lv";

/// A name (enclave, namespace, topic) as it appears in a liveliness token: every `/` written
/// `%`, and an empty name as `%` (a token may have no empty chunk).
pub fn mangle(name: &str) -> String {
    if name.is_empty() {
        "%".into()
    } else {
        name.replace('/', "%")
    }
}

/// The DDS-style type name rmw_zenoh uses: `sensor_msgs/msg/JointState` is
/// `sensor_msgs::msg::dds_::JointState_`.
pub fn dds_type_name(t: &MsgType) -> String {
    let mut parts: Vec<&str> = t.name.split('/').collect();
    let name = parts.pop().unwrap_or("");
    format!("{}::dds_::{name}_", parts.join("::"))
}

/// The key expression of topic `name` (fully qualified, `/ns/topic`) of type `t` in ROS domain
/// `domain`: one leading and one trailing `/` left out, the rest kept as key chunks.
pub fn topic_key(domain: u32, name: &str, t: &MsgType) -> Result<String, TypeHashError> {
    let name = name.strip_prefix('/').unwrap_or(name);
    let name = name.strip_suffix('/').unwrap_or(name);
    Ok(format!(
        "{domain}/{name}/{}/{}",
        dds_type_name(t),
        rihs01(t)?
    ))
}

/// The quality of service of a topic, as much of it as Ferrobot sets; deadline, lifespan and
/// liveliness are ROS 2's defaults.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Qos {
    /// Reliable (resent until received) rather than best effort.
    pub reliable: bool,
    /// Transient local: a late subscriber gets the last `depth` samples (`/tf_static`,
    /// `/robot_description`).
    pub transient_local: bool,
    /// History depth (keep last).
    pub depth: u32,
}

impl Default for Qos {
    /// ROS 2's default for topics: reliable, volatile, keep last 10.
    fn default() -> Self {
        Qos {
            reliable: true,
            transient_local: false,
            depth: 10,
        }
    }
}

impl Qos {
    /// rmw_zenoh's QoS string: `<reliability>:<durability>:<history>,<depth>:<deadline s>,<ns>:
    /// <lifespan s>,<ns>:<liveliness>,<lease s>,<ns>`, each value equal to rmw_zenoh's
    /// default (reliable, volatile, keep last 42, infinite durations, automatic) left empty.
    pub fn to_keyexpr(&self) -> String {
        // rmw's enum values: BEST_EFFORT = 2, TRANSIENT_LOCAL = 1.
        let reliability = if self.reliable { "" } else { "2" };
        let durability = if self.transient_local { "1" } else { "" };
        let depth = if self.depth == 42 {
            String::new()
        } else {
            self.depth.to_string()
        };
        format!("{reliability}:{durability}:,{depth}:,:,:,,")
    }
}

/// What a liveliness token announces.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EntityKind {
    /// A node (`NN`).
    Node,
    /// A publisher (`MP`).
    Publisher,
    /// A subscription (`MS`).
    Subscription,
    /// A service server (`SS`).
    ServiceServer,
    /// A service client (`SC`).
    ServiceClient,
}

impl EntityKind {
    /// The token's two letters.
    pub fn code(self) -> &'static str {
        match self {
            EntityKind::Node => "NN",
            EntityKind::Publisher => "MP",
            EntityKind::Subscription => "MS",
            EntityKind::ServiceServer => "SS",
            EntityKind::ServiceClient => "SC",
        }
    }
}

/// A ROS 2 node as rmw_zenoh announces it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Node {
    /// The ROS domain id (`ROS_DOMAIN_ID`, 0 by default).
    pub domain: u32,
    /// The zenoh session's id, as zenoh writes it (lowercase hex).
    pub zid: String,
    /// The node's id, unique in its session (rmw_zenoh counts nodes and entities from 0).
    pub id: u64,
    /// The security enclave, `/` by default.
    pub enclave: String,
    /// The namespace, `/` for none, `/robot1` for a robot's.
    pub namespace: String,
    /// The node's name.
    pub name: String,
}

impl Node {
    /// The node's own token: `@ros2_lv/<domain>/<zid>/<id>/<id>/NN/<enclave>/<ns>/<name>`.
    pub fn token(&self) -> String {
        format!(
            "{ADMIN_SPACE}/{}/{}/{}/{}/NN/{}/{}/{}",
            self.domain,
            self.zid,
            self.id,
            self.id,
            mangle(&self.enclave),
            mangle(&self.namespace),
            self.name
        )
    }

    /// The token of entity `id` (unique in the session) of kind `kind` on topic (or service)
    /// `topic` (fully qualified) of type `t` with `qos`.
    pub fn entity_token(
        &self,
        id: u64,
        kind: EntityKind,
        topic: &str,
        t: &MsgType,
        qos: &Qos,
    ) -> Result<String, TypeHashError> {
        Ok(format!(
            "{ADMIN_SPACE}/{}/{}/{}/{id}/{}/{}/{}/{}/{}/{}/{}/{}",
            self.domain,
            self.zid,
            self.id,
            kind.code(),
            mangle(&self.enclave),
            mangle(&self.namespace),
            self.name,
            mangle(topic),
            dds_type_name(t),
            rihs01(t)?,
            qos.to_keyexpr()
        ))
    }
}

/// An entity's GID: XXH3-128 (seed 0) of its liveliness token, low 64 bits first, each half
/// little-endian, as rmw_zenoh derives it.
pub fn gid(token: &str) -> [u8; 16] {
    twox_hash::XxHash3_128::oneshot(token.as_bytes()).to_le_bytes()
}

/// The attachment rmw_zenoh puts on every published sample (and service request and reply).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Attachment {
    /// The publisher's sequence number, from 1, one up per sample.
    pub sequence: i64,
    /// When the sample was published, ns since the UNIX epoch.
    pub timestamp_ns: i64,
    /// The publisher's GID ([`gid`]).
    pub gid: [u8; 16],
}

/// The attachment's length in bytes.
pub const ATTACHMENT_LEN: usize = 33;

/// Why bytes are not an attachment.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum AttachmentError {
    /// Not 33 bytes long.
    #[error("an rmw_zenoh attachment is {ATTACHMENT_LEN} bytes, not {0}")]
    Length(usize),
    /// The GID's length prefix is not 16.
    #[error("a GID of {0} bytes, not 16")]
    GidLength(u8),
}

impl Attachment {
    /// Its bytes: the sequence number and the time as little-endian `i64`, then the GID with
    /// zenoh's serialization of a 16-byte array (a LEB128 length, 16, first).
    pub fn encode(&self) -> [u8; ATTACHMENT_LEN] {
        let mut b = [0u8; ATTACHMENT_LEN];
        b[..8].copy_from_slice(&self.sequence.to_le_bytes());
        b[8..16].copy_from_slice(&self.timestamp_ns.to_le_bytes());
        b[16] = 16;
        b[17..].copy_from_slice(&self.gid);
        b
    }

    /// An attachment from its bytes.
    pub fn decode(b: &[u8]) -> Result<Attachment, AttachmentError> {
        let b: &[u8; ATTACHMENT_LEN] =
            b.try_into().map_err(|_| AttachmentError::Length(b.len()))?;
        if b[16] != 16 {
            return Err(AttachmentError::GidLength(b[16]));
        }
        let i64_at = |k: usize| {
            let mut a = [0u8; 8];
            a.copy_from_slice(&b[k..k + 8]);
            i64::from_le_bytes(a)
        };
        let mut gid = [0u8; 16];
        gid.copy_from_slice(&b[17..]);
        Ok(Attachment {
            sequence: i64_at(0),
            timestamp_ns: i64_at(8),
            gid,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::schemas;

    /// rmw_zenoh's design document's example, and `/joint_states` as a Jazzy node keys it.
    #[test]
    fn topic_keys_are_rmw_zenohs() {
        assert_eq!(
            topic_key(0, "/chatter", &schemas::STRING).unwrap(),
            "0/chatter/std_msgs::msg::dds_::String_/RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18"
        );
        assert_eq!(
            topic_key(0, "/robot1/joint_states", &schemas::JOINT_STATE).unwrap(),
            "0/robot1/joint_states/sensor_msgs::msg::dds_::JointState_/RIHS01_a13ee3a330e346c9d87b5aa18d24e11690752bd33a0350f11c5882bc9179260e"
        );
    }

    /// The QoS strings of rmw_zenoh's design document and its `qos_to_keyexpr`.
    #[test]
    fn qos_strings_leave_rmw_zenohs_defaults_empty() {
        let q = |reliable, transient_local, depth| Qos {
            reliable,
            transient_local,
            depth,
        };
        assert_eq!(Qos::default().to_keyexpr(), "::,10:,:,:,,");
        assert_eq!(q(true, false, 7).to_keyexpr(), "::,7:,:,:,,");
        assert_eq!(q(false, false, 10).to_keyexpr(), "2::,10:,:,:,,");
        assert_eq!(q(true, true, 1).to_keyexpr(), ":1:,1:,:,:,,");
        assert_eq!(q(true, false, 42).to_keyexpr(), "::,:,:,:,,");
    }

    #[test]
    fn tokens_mangle_names_and_never_leave_a_chunk_empty() {
        let node = Node {
            domain: 0,
            zid: "aac3178e146ba6f1fc6e6a4085e77f21".into(),
            id: 0,
            enclave: "/".into(),
            namespace: "/".into(),
            name: "ferrobot".into(),
        };
        assert_eq!(
            node.token(),
            "@ros2_lv/0/aac3178e146ba6f1fc6e6a4085e77f21/0/0/NN/%/%/ferrobot"
        );
        let publisher = node
            .entity_token(
                1,
                EntityKind::Publisher,
                "/joint_states",
                &schemas::JOINT_STATE,
                &Qos::default(),
            )
            .unwrap();
        assert_eq!(publisher, "@ros2_lv/0/aac3178e146ba6f1fc6e6a4085e77f21/0/1/MP/%/%/ferrobot/%joint_states/sensor_msgs::msg::dds_::JointState_/RIHS01_a13ee3a330e346c9d87b5aa18d24e11690752bd33a0350f11c5882bc9179260e/::,10:,:,:,,");
        assert!(!publisher.contains("//"));
        assert_eq!(mangle(""), "%");
        assert_eq!(mangle("/robot1"), "%robot1");
    }

    /// The layout of rmw_zenoh's design document, and bytes that are not one.
    #[test]
    fn attachments_are_33_bytes_and_anything_else_is_refused() {
        let mut gid = [0u8; 16];
        for (k, g) in gid.iter_mut().enumerate() {
            *g = k as u8;
        }
        let a = Attachment {
            sequence: 1,
            timestamp_ns: 1_700_000_000_000_000_000,
            gid,
        };
        let b = a.encode();
        assert_eq!(
            b[..17],
            [1, 0, 0, 0, 0, 0, 0, 0, 0x00, 0x00, 0x2a, 0x36, 0xfe, 0x9c, 0x97, 0x17, 0x10]
        );
        assert_eq!(Attachment::decode(&b), Ok(a));
        assert_eq!(
            Attachment::decode(&b[..32]),
            Err(AttachmentError::Length(32))
        );
        let mut bad = b;
        bad[16] = 15;
        assert_eq!(
            Attachment::decode(&bad),
            Err(AttachmentError::GidLength(15))
        );
    }

    #[test]
    fn gids_are_xxh3_128_of_the_token_low_half_first() {
        // XXH3-128 of the empty input (seed 0) is 99aa06d3014798d86001c324468d497f: low half
        // 6001c324468d497f, little-endian first.
        assert_eq!(
            gid(""),
            [
                0x7f, 0x49, 0x8d, 0x46, 0x24, 0xc3, 0x01, 0x60, 0xd8, 0x98, 0x47, 0x01, 0xd3, 0x06,
                0xaa, 0x99
            ]
        );
        assert_ne!(gid("a"), gid("b"));
    }
}
