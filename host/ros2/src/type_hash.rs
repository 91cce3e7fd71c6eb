//! RIHS01 type hashes: what ROS 2 (Jazzy and later) calls a message type's version, carried in
//! every rmw_zenoh key expression and checked when a publisher and a subscriber meet.
//!
//! `rosidl` computes it from the type's description: the type and every type it uses
//! (transitively, sorted by name), each as its name and fields (name, type id, capacity,
//! string capacity, nested type name; constants and default values left out), written as JSON
//! with `", "` and `": "` separators, hashed with SHA-256 and written `RIHS01_` + 64 lowercase
//! hex digits (`rosidl_generator_type_description`). Here that is done from the `.msg` texts
//! of [`crate::schemas`], so one definition gives both the MCAP schema and the hash.

use sha2::{Digest, Sha256};

use crate::schemas::MsgType;

/// `rosidl`'s field type ids (`type_description_interfaces/msg/FieldType`): a nested type.
const NESTED: u8 = 1;
/// A bounded string (`string<=N`).
const BOUNDED_STRING: u8 = 21;
/// A bounded wide string (`wstring<=N`).
const BOUNDED_WSTRING: u8 = 22;
/// Added to an element's id for a fixed array (`T[N]`).
const FIXED_ARRAY: u8 = 48;
/// Added for a bounded sequence (`T[<=N]`).
const BOUNDED_SEQUENCE: u8 = 96;
/// Added for an unbounded sequence (`T[]`).
const UNBOUNDED_SEQUENCE: u8 = 144;

/// The id of a primitive `.msg` type (`char` is IDL's `uint8`, as `rosidl` maps it).
fn primitive_id(t: &str) -> Option<u8> {
    Some(match t {
        "int8" => 2,
        "uint8" | "char" => 3,
        "int16" => 4,
        "uint16" => 5,
        "int32" => 6,
        "uint32" => 7,
        "int64" => 8,
        "uint64" => 9,
        "float32" => 10,
        "float64" => 11,
        "bool" => 15,
        "byte" => 16,
        "string" => 17,
        "wstring" => 18,
        _ => return None,
    })
}

/// One field of a type description.
#[derive(Debug, Clone, PartialEq, Eq)]
struct Field {
    name: String,
    type_id: u8,
    capacity: u64,
    string_capacity: u64,
    nested: String,
}

/// Why a definition could not be described.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{type_name}: {reason}")]
pub struct TypeHashError {
    /// The type whose definition failed.
    pub type_name: &'static str,
    /// The line, and what was wrong with it.
    pub reason: String,
}

/// The fields of `t`'s definition, nested types resolved against what it uses.
fn fields(t: &MsgType) -> Result<Vec<Field>, TypeHashError> {
    let err = |reason: String| TypeHashError {
        type_name: t.name,
        reason,
    };
    let package = t.name.split('/').next().unwrap_or("");
    let mut out = Vec::new();
    for line in t.definition.lines().map(str::trim) {
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let mut words = line.split_whitespace();
        let (Some(ty), Some(name)) = (words.next(), words.next()) else {
            return Err(err(format!("`{line}`: no type and name")));
        };
        // A constant (`byte DEBUG=10`), not a field.
        if name.contains('=') {
            continue;
        }
        let (base, array) = match ty.find('[') {
            Some(i) => (&ty[..i], Some(&ty[i..])),
            None => (ty, None),
        };
        let mut f = element(base, package, t).ok_or_else(|| err(format!("`{line}`: type")))?;
        f.name = name.to_string();
        match array {
            None => {}
            Some("[]") => f.type_id += UNBOUNDED_SEQUENCE,
            Some(a) => {
                let inner = a
                    .strip_prefix('[')
                    .and_then(|a| a.strip_suffix(']'))
                    .ok_or_else(|| err(format!("`{line}`: array")))?;
                let (bounded, n) = match inner.strip_prefix("<=") {
                    Some(n) => (true, n),
                    None => (false, inner),
                };
                f.capacity = n
                    .parse()
                    .map_err(|_| err(format!("`{line}`: array size")))?;
                f.type_id += if bounded {
                    BOUNDED_SEQUENCE
                } else {
                    FIXED_ARRAY
                };
            }
        }
        out.push(f);
    }
    if out.is_empty() {
        // An empty message is described with the member IDL gives it.
        out.push(Field {
            name: "structure_needs_at_least_one_member".into(),
            type_id: 3,
            capacity: 0,
            string_capacity: 0,
            nested: String::new(),
        });
    }
    Ok(out)
}

/// The element type `base` (no array suffix) of a field of `t` (in `package`).
fn element(base: &str, package: &str, t: &MsgType) -> Option<Field> {
    let field = |type_id, string_capacity, nested: String| Field {
        name: String::new(),
        type_id,
        capacity: 0,
        string_capacity,
        nested,
    };
    if let Some(id) = primitive_id(base) {
        return Some(field(id, 0, String::new()));
    }
    for (prefix, id) in [("string<=", BOUNDED_STRING), ("wstring<=", BOUNDED_WSTRING)] {
        if let Some(n) = base.strip_prefix(prefix) {
            return Some(field(id, n.parse().ok()?, String::new()));
        }
    }
    // A nested type: `pkg/Type`, or `Type` of the same package.
    let (pkg, name) = base.split_once('/').unwrap_or((package, base));
    let full = format!("{pkg}/msg/{name}");
    t.uses
        .iter()
        .any(|u| u.name == full)
        .then(|| field(NESTED, 0, full))
}

/// Every type `t` uses, transitively, each once, sorted by name.
fn referenced(t: &MsgType) -> Vec<&'static MsgType> {
    let mut all: Vec<&'static MsgType> = Vec::new();
    let mut todo: Vec<&'static MsgType> = t.uses.to_vec();
    while let Some(u) = todo.pop() {
        if !all.iter().any(|a| a.name == u.name) {
            all.push(u);
            todo.extend_from_slice(u.uses);
        }
    }
    all.sort_by_key(|u| u.name);
    all
}

/// A JSON string (the names are ASCII; quotes and backslashes escaped all the same).
fn json_string(s: &str, out: &mut String) {
    out.push('"');
    for c in s.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            c if c.is_ascii() && !c.is_ascii_control() => out.push(c),
            c => out.push_str(&format!("\\u{:04x}", c as u32)),
        }
    }
    out.push('"');
}

/// One type's description as `rosidl` writes it for hashing.
fn individual(t: &MsgType, out: &mut String) -> Result<(), TypeHashError> {
    out.push_str("{\"type_name\": ");
    json_string(t.name, out);
    out.push_str(", \"fields\": [");
    for (k, f) in fields(t)?.iter().enumerate() {
        if k > 0 {
            out.push_str(", ");
        }
        out.push_str("{\"name\": ");
        json_string(&f.name, out);
        out.push_str(&format!(
            ", \"type\": {{\"type_id\": {}, \"capacity\": {}, \"string_capacity\": {}, \"nested_type_name\": ",
            f.type_id, f.capacity, f.string_capacity
        ));
        json_string(&f.nested, out);
        out.push_str("}}");
    }
    out.push_str("]}");
    Ok(())
}

/// The JSON text of `t`'s type description that its hash is taken of.
pub fn description_json(t: &MsgType) -> Result<String, TypeHashError> {
    let mut out = String::from("{\"type_description\": ");
    individual(t, &mut out)?;
    out.push_str(", \"referenced_type_descriptions\": [");
    for (k, u) in referenced(t).into_iter().enumerate() {
        if k > 0 {
            out.push_str(", ");
        }
        individual(u, &mut out)?;
    }
    out.push_str("]}");
    Ok(out)
}

/// `t`'s RIHS01 type hash, `RIHS01_` and 64 lowercase hex digits.
pub fn rihs01(t: &MsgType) -> Result<String, TypeHashError> {
    let digest = Sha256::digest(description_json(t)?.as_bytes());
    let mut s = String::from("RIHS01_");
    for b in digest {
        s.push_str(&format!("{b:02x}"));
    }
    Ok(s)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::schemas;

    /// The hashes ROS 2 Jazzy publishes for these types (as `ros2 topic info --verbose` and
    /// rmw_zenoh's design document show them): our definitions must give exactly these, or no
    /// ROS 2 node would take our topics for its own.
    #[test]
    fn our_definitions_hash_as_ros_2_jazzy_does() {
        for (t, hash) in [
            (
                &schemas::STRING,
                "df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18",
            ),
            (
                &schemas::JOINT_STATE,
                "a13ee3a330e346c9d87b5aa18d24e11690752bd33a0350f11c5882bc9179260e",
            ),
            (
                &schemas::TWIST,
                "9c45bf16fe0983d80e3cfe750d6835843d265a9a6c46bd2e609fcddde6fb8d2a",
            ),
            (
                &schemas::TF_MESSAGE,
                "e369d0f05a23ae52508854b66f6aa0437f3449d652e8cbf22d5abe85d020f087",
            ),
            (
                &schemas::ODOMETRY,
                "3cc97dc7fb7502f8714462c526d369e35b603cfc34d946e3f2eda2766dfec6e0",
            ),
            (
                &schemas::IMAGE,
                "d31d41a9a4c4bc8eae9be757b0beed306564f7526c88ea6a4588fb9582527d47",
            ),
            (
                &schemas::CAMERA_INFO,
                "b3dfd68ff46c9d56c80fd3bd4ed22c7a4ddce8c8348f2f59c299e73118e7e275",
            ),
            (
                &schemas::JOINT_TRAJECTORY,
                "179b33eba59d676f6d967ac71fe35e7ca2f64b2f3928f4a018cec115e213796e",
            ),
            (
                &schemas::HEADER,
                "f49fb3ae2cf070f793645ff749683ac6b06203e41c891e17701b1cb597ce6a01",
            ),
            (
                &schemas::POSE_STAMPED,
                "10f3786d7d40fd2b54367835614bff85d4ad3b5dab62bf8bca0cc232d73b4cd8",
            ),
            (
                &schemas::TRANSFORM_STAMPED,
                "0a241f87d04668d94099cbb5ba11691d5ad32c2f29682e4eb5653424bd275206",
            ),
            (
                &schemas::POINT_CLOUD2,
                "9198cabf7da3796ae6fe19c4cb3bdd3525492988c70522628af5daa124bae2b5",
            ),
            (
                &schemas::OCCUPANCY_GRID,
                "8d348150c12913a31ee0ec170fbf25089e4745d17035792a1ba94d6f0bc0cfc7",
            ),
        ] {
            assert_eq!(rihs01(t).unwrap(), format!("RIHS01_{hash}"), "{}", t.name);
        }
    }

    #[test]
    fn a_description_lists_fields_by_id_and_referenced_types_by_name() {
        let j = description_json(&schemas::JOINT_STATE).unwrap();
        assert!(j.starts_with("{\"type_description\": {\"type_name\": \"sensor_msgs/msg/JointState\", \"fields\": [{\"name\": \"header\", \"type\": {\"type_id\": 1, \"capacity\": 0, \"string_capacity\": 0, \"nested_type_name\": \"std_msgs/msg/Header\"}}"), "{j}");
        // string[] name: 17 + 144.
        assert!(
            j.contains("{\"name\": \"name\", \"type\": {\"type_id\": 161,"),
            "{j}"
        );
        let time = j.find("builtin_interfaces/msg/Time").unwrap();
        let header = j.rfind("\"type_name\": \"std_msgs/msg/Header\"").unwrap();
        assert!(time < header, "referenced types sorted by name: {j}");
        // Constants are not fields.
        assert!(!description_json(&schemas::LOG).unwrap().contains("DEBUG"));
    }
}
