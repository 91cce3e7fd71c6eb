//! Foxglove's WebSocket protocol (subprotocol `foxglove.websocket.v1`), the part a server of
//! ROS 2 messages needs, sans-IO: the JSON the server says (server info, channels advertised),
//! the JSON a client says (subscribe, unsubscribe), and the binary frame of one message.
//! Reference: `foxglove/ws-protocol`, `docs/spec.md`.

use serde::{Deserialize, Serialize};

/// The subprotocol a client asks for and the server selects.
pub const SUBPROTOCOL: &str = "foxglove.websocket.v1";
/// The binary opcode of a message's data.
pub const MESSAGE_DATA: u8 = 1;

/// A channel: one topic, its ROS 2 type and schema, CDR-encoded.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
#[serde(rename_all = "camelCase")]
pub struct Channel {
    /// The channel's id, unique in the server.
    pub id: u32,
    /// The topic, `/joint_states`.
    pub topic: String,
    /// The messages' encoding: `cdr`.
    pub encoding: &'static str,
    /// The type, `sensor_msgs/msg/JointState`.
    pub schema_name: String,
    /// The type's definition with every type it uses (rosbag2's `ros2msg` text).
    pub schema: String,
    /// `ros2msg`.
    pub schema_encoding: &'static str,
}

/// What the server says.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "op", rename_all = "camelCase")]
pub enum ServerMsg<'a> {
    /// Said first: who it is and what it can do.
    #[serde(rename_all = "camelCase")]
    ServerInfo {
        /// Its name.
        name: &'a str,
        /// Optional features: none.
        capabilities: [&'a str; 0],
        /// Client-published encodings: none.
        supported_encodings: [&'a str; 0],
        /// This run's id.
        session_id: &'a str,
    },
    /// The channels a client may subscribe to.
    Advertise {
        /// The channels.
        channels: &'a [Channel],
    },
    /// A status line for the client's problems panel.
    Status {
        /// 0 info, 1 warning, 2 error.
        level: u8,
        /// The words.
        message: &'a str,
    },
}

/// One subscription a client asks for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "camelCase")]
pub struct Subscription {
    /// The client's id for it.
    pub id: u32,
    /// The channel.
    pub channel_id: u32,
}

/// What a client says (the ops a read-only server understands; others are ignored).
#[derive(Debug, Clone, PartialEq, Eq, Deserialize)]
#[serde(tag = "op", rename_all = "camelCase")]
pub enum ClientMsg {
    /// Start sending these channels.
    Subscribe {
        /// The subscriptions.
        subscriptions: Vec<Subscription>,
    },
    /// Stop sending these.
    #[serde(rename_all = "camelCase")]
    Unsubscribe {
        /// The subscriptions' ids.
        subscription_ids: Vec<u32>,
    },
}

/// A client's text, or why it is not one this server understands.
pub fn client_msg(text: &str) -> Result<ClientMsg, serde_json::Error> {
    serde_json::from_str(text)
}

/// The binary frame of one message on subscription `sub`, logged at `time_ns`: opcode, the
/// subscription id (u32 LE), the time (u64 LE, ns), the CDR payload.
pub fn message_data(sub: u32, time_ns: u64, payload: &[u8]) -> Vec<u8> {
    let mut b = Vec::with_capacity(13 + payload.len());
    b.push(MESSAGE_DATA);
    b.extend_from_slice(&sub.to_le_bytes());
    b.extend_from_slice(&time_ns.to_le_bytes());
    b.extend_from_slice(payload);
    b
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_spec_examples_parse_and_the_frame_is_laid_out() {
        let s =
            r#"{"op":"subscribe","subscriptions":[{"id":0,"channelId":3},{"id":1,"channelId":5}]}"#;
        assert_eq!(
            client_msg(s).unwrap(),
            ClientMsg::Subscribe {
                subscriptions: vec![
                    Subscription {
                        id: 0,
                        channel_id: 3
                    },
                    Subscription {
                        id: 1,
                        channel_id: 5
                    }
                ]
            }
        );
        let u = r#"{"op":"unsubscribe","subscriptionIds":[0,1]}"#;
        assert_eq!(
            client_msg(u).unwrap(),
            ClientMsg::Unsubscribe {
                subscription_ids: vec![0, 1]
            }
        );
        assert!(client_msg(r#"{"op":"subscribe"}"#).is_err());
        assert!(client_msg("not json").is_err());
        let f = message_data(7, 0x0102, &[9, 9]);
        assert_eq!(f, [1, 7, 0, 0, 0, 2, 1, 0, 0, 0, 0, 0, 0, 9, 9]);
        let a = serde_json::to_string(&ServerMsg::Advertise {
            channels: &[Channel {
                id: 1,
                topic: "/tf".into(),
                encoding: "cdr",
                schema_name: "tf2_msgs/msg/TFMessage".into(),
                schema: "x".into(),
                schema_encoding: "ros2msg",
            }],
        })
        .unwrap();
        assert_eq!(
            a,
            r#"{"op":"advertise","channels":[{"id":1,"topic":"/tf","encoding":"cdr","schemaName":"tf2_msgs/msg/TFMessage","schema":"x","schemaEncoding":"ros2msg"}]}"#
        );
    }
}
