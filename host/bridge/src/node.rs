//! A ROS 2 node as rmw_zenoh makes one: its liveliness token, and publishers and subscriptions
//! that announce themselves the same way, put each sample with rmw_zenoh's attachment
//! (sequence number, source time, GID) and key it by topic, type and type hash.

use std::sync::atomic::{AtomicI64, AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{SystemTime, UNIX_EPOCH};

use ferrobot_ros2::rmw_zenoh::{self, Attachment, EntityKind, Node, Qos};
use ferrobot_ros2::topics::Topic;
use zenoh::liveliness::LivelinessToken;
use zenoh::pubsub::Subscriber;
use zenoh::{Session, Wait};
use zenoh_ext::{AdvancedPublisher, AdvancedPublisherBuilderExt, CacheConfig};

use crate::error::BridgeError;

/// A ROS 2 node on a zenoh session.
pub struct RosNode {
    session: Session,
    node: Node,
    /// rmw_zenoh numbers a session's nodes and entities from one counter.
    next_id: Arc<AtomicU64>,
    _token: LivelinessToken,
}

/// The quality of service ROS 2 gives `topic`'s publishers: transient local, depth 1, for what
/// is said once and holds ([`Topic::latched`]: `/robot_description`, `/tf_static`, `/map`, …);
/// reliable, volatile, depth 10 (ROS 2's default) for the rest.
pub fn qos_of(topic: &Topic) -> Qos {
    if topic.latched() {
        Qos {
            reliable: true,
            transient_local: true,
            depth: 1,
        }
    } else {
        Qos::default()
    }
}

/// A ROS 2 name checked as `rcl` does for what Ferrobot gives it: `/`, or `/` followed by
/// segments of letters, digits and `_` that do not start with a digit.
pub fn check_namespace(ns: &str) -> Result<(), BridgeError> {
    let ok = ns == "/"
        || (ns.starts_with('/')
            && ns[1..].split('/').all(|seg| {
                !seg.is_empty()
                    && !seg.starts_with(|c: char| c.is_ascii_digit())
                    && seg.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
            }));
    match ok {
        true => Ok(()),
        false => Err(BridgeError::Usage(format!(
            "namespace {ns:?}: ROS 2 wants `/` or `/name[/name…]` (letters, digits, `_`; no \
             leading digit)"
        ))),
    }
}

impl RosNode {
    /// Node `name` in namespace `namespace` (`/` for none) of ROS domain `domain`, announced on
    /// `session`.
    pub fn new(
        session: &Session,
        domain: u32,
        namespace: &str,
        name: &str,
    ) -> Result<RosNode, BridgeError> {
        check_namespace(namespace)?;
        check_namespace(&format!("/{name}"))?;
        let next_id = Arc::new(AtomicU64::new(0));
        let node = Node {
            domain,
            zid: session.zid().to_string(),
            id: next_id.fetch_add(1, Ordering::Relaxed),
            enclave: "/".into(),
            namespace: namespace.into(),
            name: name.into(),
        };
        let token = session
            .liveliness()
            .declare_token(node.token())
            .wait()
            .map_err(|e| BridgeError::zenoh("announcing the node", e))?;
        Ok(RosNode {
            session: session.clone(),
            node,
            next_id,
            _token: token,
        })
    }

    /// Declares an entity's liveliness token (`what` names it in an error).
    fn announce(&self, token: String, what: &str) -> Result<LivelinessToken, BridgeError> {
        self.session
            .liveliness()
            .declare_token(token)
            .wait()
            .map_err(|e| BridgeError::zenoh(what, e))
    }

    /// The topic's fully qualified name in this node's namespace.
    pub fn full_name(&self, topic: &str) -> String {
        match self.node.namespace.as_str() {
            "/" => topic.to_string(),
            ns => format!("{ns}{topic}"),
        }
    }

    /// The entity token and key expression of `topic` as `kind`, and its GID.
    fn entity(
        &self,
        kind: EntityKind,
        topic: &Topic,
        qos: &Qos,
    ) -> Result<(String, String, [u8; 16]), BridgeError> {
        let name = self.full_name(topic.name);
        let id = self.next_id.fetch_add(1, Ordering::Relaxed);
        let token = self.node.entity_token(id, kind, &name, topic.msg, qos)?;
        let key = rmw_zenoh::topic_key(self.node.domain, &name, topic.msg)?;
        let gid = rmw_zenoh::gid(&token);
        Ok((token, key, gid))
    }

    /// A publisher on `topic` with ROS 2's QoS for it ([`qos_of`]); transient local keeps its
    /// last samples for late subscribers, as rmw_zenoh's AdvancedPublisher does.
    pub fn publisher(&self, topic: &Topic) -> Result<RosPublisher, BridgeError> {
        let qos = qos_of(topic);
        let (token, key, gid) = self.entity(EntityKind::Publisher, topic, &qos)?;
        let what = format!("declaring the publisher of {}", topic.name);
        let mut b = self.session.declare_publisher(key.clone()).advanced();
        if qos.transient_local {
            b = b
                .cache(CacheConfig::default().max_samples(qos.depth as usize))
                .publisher_detection();
        }
        let publisher = b.wait().map_err(|e| BridgeError::zenoh(&what, e))?;
        let token = self.announce(token, &what)?;
        Ok(RosPublisher {
            publisher,
            key,
            gid,
            sequence: AtomicI64::new(0),
            _token: token,
        })
    }

    /// A subscription to `topic`: `on_sample` gets each sample's payload (CDR) and attachment
    /// (rmw_zenoh's 33 bytes, empty when there is none), on zenoh's thread.
    pub fn subscription(
        &self,
        topic: &Topic,
        on_sample: impl Fn(&[u8], &[u8]) + Send + Sync + 'static,
    ) -> Result<RosSubscription, BridgeError> {
        let qos = Qos::default();
        let (token, key, _) = self.entity(EntityKind::Subscription, topic, &qos)?;
        let what = format!("declaring the subscription to {}", topic.name);
        let subscriber = self
            .session
            .declare_subscriber(key)
            // What this session publishes itself is not input.
            .allowed_origin(zenoh::sample::Locality::Remote)
            .callback(move |sample| {
                let payload = sample.payload().to_bytes();
                let attachment = sample.attachment().map(|a| a.to_bytes());
                on_sample(&payload, attachment.as_deref().unwrap_or(&[]));
            })
            .wait()
            .map_err(|e| BridgeError::zenoh(&what, e))?;
        let token = self.announce(token, &what)?;
        Ok(RosSubscription {
            _subscriber: subscriber,
            _token: token,
        })
    }
}

/// A publisher of one topic.
pub struct RosPublisher {
    publisher: AdvancedPublisher<'static>,
    key: String,
    gid: [u8; 16],
    sequence: AtomicI64,
    _token: LivelinessToken,
}

impl RosPublisher {
    /// Whether any subscriber matches this publisher now (yes when zenoh cannot say).
    pub fn matched(&self) -> bool {
        self.publisher
            .matching_status()
            .wait()
            .map_or(true, |m| m.matching())
    }

    /// Puts one sample: `cdr` (with its encapsulation header), with the next sequence number and
    /// this instant as its source time.
    pub fn put(&self, cdr: Vec<u8>) -> Result<(), BridgeError> {
        let sequence = self.sequence.fetch_add(1, Ordering::Relaxed) + 1;
        let now = SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .unwrap_or_default();
        let attachment = Attachment {
            sequence,
            timestamp_ns: i64::try_from(now.as_nanos()).unwrap_or(i64::MAX),
            gid: self.gid,
        };
        self.publisher
            .put(cdr)
            .attachment(attachment.encode().to_vec())
            .wait()
            .map_err(|e| BridgeError::zenoh(format!("publishing on {}", self.key), e))
    }

    /// Its key expression.
    pub fn key(&self) -> &str {
        &self.key
    }

    /// Samples put so far.
    pub fn sent(&self) -> u64 {
        self.sequence.load(Ordering::Relaxed) as u64
    }
}

/// A subscription to one topic; dropping it ends it.
pub struct RosSubscription {
    _subscriber: Subscriber<()>,
    _token: LivelinessToken,
}
