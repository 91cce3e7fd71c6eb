//! The view's state, sans-IO: the channels (one per topic, made as topics are first sent), the
//! latest message of each latched topic, and each client's subscriptions and outgoing queue.
//! Fed messages and clients' words; what goes to each client leaves through its queue, which
//! drops what a slow viewer cannot take rather than hold the robot.

use std::collections::HashMap;
use std::sync::mpsc::{SyncSender, TrySendError};

use ferrobot_ros2::topics::Topic;

use crate::protocol::{self, Channel, ClientMsg, ServerMsg};

/// A frame for a client.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Out {
    /// JSON.
    Text(String),
    /// A message's data.
    Binary(Vec<u8>),
}

struct Client {
    out: SyncSender<Out>,
    /// Channel id to the client's subscription id.
    subs: HashMap<u32, u32>,
}

/// Counters.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct HubStats {
    /// Clients connected so far.
    pub clients: u64,
    /// Messages sent to clients.
    pub sent: u64,
    /// Messages dropped for a client whose queue was full.
    pub dropped: u64,
    /// Client texts that were not the protocol's.
    pub bad_requests: u64,
}

/// The view's channels and clients.
#[derive(Default)]
pub struct Hub {
    name: String,
    session: String,
    channels: Vec<Channel>,
    by_topic: HashMap<&'static str, u32>,
    latched: HashMap<u32, (u64, Vec<u8>)>,
    clients: HashMap<u64, Client>,
    next_client: u64,
    stats: HubStats,
    /// Messages published on each channel (by id − 1, one per channel), whether or not anyone
    /// took them.
    published: Vec<u64>,
}

fn json(m: &ServerMsg<'_>) -> String {
    serde_json::to_string(m).unwrap_or_default()
}

impl Hub {
    /// A hub named `name` (the server's name clients show).
    pub fn new(name: &str, session: &str) -> Hub {
        Hub {
            name: name.into(),
            session: session.into(),
            ..Hub::default()
        }
    }

    /// The counters.
    pub fn stats(&self) -> HubStats {
        self.stats
    }

    /// The channel of `topic`, made and advertised to every client the first time.
    pub fn channel(&mut self, topic: &Topic) -> u32 {
        if let Some(&id) = self.by_topic.get(topic.name) {
            return id;
        }
        let id = self.channels.len() as u32 + 1;
        let c = Channel {
            id,
            topic: topic.name.into(),
            encoding: "cdr",
            schema_name: topic.msg.name.into(),
            schema: topic.msg.schema(),
            schema_encoding: "ros2msg",
        };
        let text = json(&ServerMsg::Advertise {
            channels: std::slice::from_ref(&c),
        });
        self.channels.push(c);
        self.published.push(0);
        self.by_topic.insert(topic.name, id);
        for client in self.clients.values() {
            let _ = client.out.try_send(Out::Text(text.clone()));
        }
        id
    }

    /// Messages published on the topic named `topic` so far, whether or not anyone took them.
    pub fn published(&self, topic: &str) -> u64 {
        self.by_topic
            .get(topic)
            .and_then(|&id| self.published.get(id as usize - 1))
            .copied()
            .unwrap_or(0)
    }

    /// Whether any client subscribes to one of `topics`.
    pub fn wanted(&self, topics: &[Topic]) -> bool {
        let mut ids = topics.iter().filter_map(|t| self.by_topic.get(t.name));
        ids.any(|id| self.clients.values().any(|c| c.subs.contains_key(id)))
    }

    /// A new client: told who the server is and every channel so far; its id.
    pub fn join(&mut self, out: SyncSender<Out>) -> u64 {
        let id = self.next_client;
        self.next_client += 1;
        let info = json(&ServerMsg::ServerInfo {
            name: &self.name,
            capabilities: [],
            supported_encodings: [],
            session_id: &self.session,
        });
        let _ = out.try_send(Out::Text(info));
        let ads = json(&ServerMsg::Advertise {
            channels: &self.channels,
        });
        let _ = out.try_send(Out::Text(ads));
        self.clients.insert(
            id,
            Client {
                out,
                subs: HashMap::new(),
            },
        );
        self.stats.clients += 1;
        id
    }

    /// Client `id` has gone.
    pub fn leave(&mut self, id: u64) {
        self.clients.remove(&id);
    }

    /// Client `id` said `text`: a subscription gets a latched channel's message at once; what
    /// is not the protocol is answered with a status and counted.
    pub fn client_says(&mut self, id: u64, text: &str) {
        let Some(client) = self.clients.get_mut(&id) else {
            return;
        };
        match protocol::client_msg(text) {
            Ok(ClientMsg::Subscribe { subscriptions }) => {
                for s in subscriptions {
                    client.subs.insert(s.channel_id, s.id);
                    if let Some((t, data)) = self.latched.get(&s.channel_id) {
                        let frame = protocol::message_data(s.id, *t, data);
                        let _ = client.out.try_send(Out::Binary(frame));
                    }
                }
            }
            Ok(ClientMsg::Unsubscribe { subscription_ids }) => {
                client.subs.retain(|_, sub| !subscription_ids.contains(sub));
            }
            Err(e) => {
                self.stats.bad_requests += 1;
                let text = json(&ServerMsg::Status {
                    level: 1,
                    message: &format!("not understood: {e}"),
                });
                let _ = client.out.try_send(Out::Text(text));
            }
        }
    }

    /// Sends `data` on `topic`, logged at `time_ns`, to its subscribers; a latched topic's
    /// message is also kept for later subscribers.
    pub fn publish(&mut self, topic: &Topic, time_ns: u64, data: Vec<u8>, latched: bool) {
        let ch = self.channel(topic);
        self.published[ch as usize - 1] += 1;
        for client in self.clients.values() {
            let Some(&sub) = client.subs.get(&ch) else {
                continue;
            };
            let frame = protocol::message_data(sub, time_ns, &data);
            match client.out.try_send(Out::Binary(frame)) {
                Ok(()) => self.stats.sent += 1,
                Err(TrySendError::Full(_)) => self.stats.dropped += 1,
                Err(TrySendError::Disconnected(_)) => {}
            }
        }
        if latched {
            self.latched.insert(ch, (time_ns, data));
        }
    }
}
