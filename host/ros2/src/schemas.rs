//! The ROS 2 message definitions our recordings use, as MCAP `ros2msg` schemas: each type's
//! `.msg` text, then every type it uses, each after a line of 80 `=` and `MSG: pkg/Type`, as
//! rosbag2 writes them (Foxglove, Lichtblick and rosbags parse this). The texts are those of
//! ROS 2 Jazzy's interfaces, comments left out; their RIHS01 hashes ([`crate::type_hash`]) are
//! checked against ROS 2's own.

/// A ROS 2 message type: its name (`pkg/msg/Type`), its definition, and the types it uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MsgType {
    /// The full name, `pkg/msg/Type`.
    pub name: &'static str,
    /// The `.msg` text.
    pub definition: &'static str,
    /// The types its fields use, directly.
    pub uses: &'static [&'static MsgType],
}

macro_rules! msg {
    ($id:ident, $name:literal, [$($dep:ident),*], $def:literal) => {
        #[doc = concat!("`", $name, "`.")]
        pub const $id: MsgType = MsgType { name: $name, definition: $def, uses: &[$(&$dep),*] };
    };
}

msg!(
    TIME,
    "builtin_interfaces/msg/Time",
    [],
    "int32 sec\nuint32 nanosec\n"
);
msg!(
    CLOCK,
    "rosgraph_msgs/msg/Clock",
    [TIME],
    "builtin_interfaces/Time clock\n"
);
msg!(
    DURATION,
    "builtin_interfaces/msg/Duration",
    [],
    "int32 sec\nuint32 nanosec\n"
);
msg!(
    HEADER,
    "std_msgs/msg/Header",
    [TIME],
    "builtin_interfaces/Time stamp\nstring frame_id\n"
);
msg!(STRING, "std_msgs/msg/String", [], "string data\n");
msg!(INT8, "std_msgs/msg/Int8", [], "int8 data\n");
msg!(
    VECTOR3,
    "geometry_msgs/msg/Vector3",
    [],
    "float64 x\nfloat64 y\nfloat64 z\n"
);
msg!(
    POINT,
    "geometry_msgs/msg/Point",
    [],
    "float64 x\nfloat64 y\nfloat64 z\n"
);
msg!(
    QUATERNION,
    "geometry_msgs/msg/Quaternion",
    [],
    "float64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1\n"
);
msg!(
    POSE,
    "geometry_msgs/msg/Pose",
    [POINT, QUATERNION],
    "Point position\nQuaternion orientation\n"
);
msg!(
    POSE_STAMPED,
    "geometry_msgs/msg/PoseStamped",
    [HEADER, POSE],
    "std_msgs/Header header\nPose pose\n"
);
msg!(
    POSE_WITH_COVARIANCE,
    "geometry_msgs/msg/PoseWithCovariance",
    [POSE],
    "Pose pose\nfloat64[36] covariance\n"
);
msg!(
    TWIST,
    "geometry_msgs/msg/Twist",
    [VECTOR3],
    "Vector3 linear\nVector3 angular\n"
);
msg!(
    TWIST_WITH_COVARIANCE,
    "geometry_msgs/msg/TwistWithCovariance",
    [TWIST],
    "Twist twist\nfloat64[36] covariance\n"
);
msg!(
    TRANSFORM,
    "geometry_msgs/msg/Transform",
    [VECTOR3, QUATERNION],
    "Vector3 translation\nQuaternion rotation\n"
);
msg!(
    TRANSFORM_STAMPED,
    "geometry_msgs/msg/TransformStamped",
    [HEADER, TRANSFORM],
    "std_msgs/Header header\nstring child_frame_id\nTransform transform\n"
);
msg!(
    TF_MESSAGE,
    "tf2_msgs/msg/TFMessage",
    [TRANSFORM_STAMPED],
    "geometry_msgs/TransformStamped[] transforms\n"
);
msg!(
    JOINT_STATE,
    "sensor_msgs/msg/JointState",
    [HEADER],
    "std_msgs/Header header\nstring[] name\nfloat64[] position\nfloat64[] velocity\nfloat64[] effort\n"
);
msg!(
    IMAGE,
    "sensor_msgs/msg/Image",
    [HEADER],
    "std_msgs/Header header\nuint32 height\nuint32 width\nstring encoding\nuint8 is_bigendian\nuint32 step\nuint8[] data\n"
);
msg!(
    REGION_OF_INTEREST,
    "sensor_msgs/msg/RegionOfInterest",
    [],
    "uint32 x_offset\nuint32 y_offset\nuint32 height\nuint32 width\nbool do_rectify\n"
);
msg!(
    CAMERA_INFO,
    "sensor_msgs/msg/CameraInfo",
    [HEADER, REGION_OF_INTEREST],
    "std_msgs/Header header\nuint32 height\nuint32 width\nstring distortion_model\nfloat64[] d\nfloat64[9] k\nfloat64[9] r\nfloat64[12] p\nuint32 binning_x\nuint32 binning_y\nRegionOfInterest roi\n"
);
msg!(
    ODOMETRY,
    "nav_msgs/msg/Odometry",
    [HEADER, POSE_WITH_COVARIANCE, TWIST_WITH_COVARIANCE],
    "std_msgs/Header header\nstring child_frame_id\ngeometry_msgs/PoseWithCovariance pose\ngeometry_msgs/TwistWithCovariance twist\n"
);
msg!(
    JOINT_TRAJECTORY_POINT,
    "trajectory_msgs/msg/JointTrajectoryPoint",
    [DURATION],
    "float64[] positions\nfloat64[] velocities\nfloat64[] accelerations\nfloat64[] effort\nbuiltin_interfaces/Duration time_from_start\n"
);
msg!(
    JOINT_TRAJECTORY,
    "trajectory_msgs/msg/JointTrajectory",
    [HEADER, JOINT_TRAJECTORY_POINT],
    "std_msgs/Header header\nstring[] joint_names\nJointTrajectoryPoint[] points\n"
);
msg!(
    POINT_FIELD,
    "sensor_msgs/msg/PointField",
    [],
    "uint8 INT8=1\nuint8 UINT8=2\nuint8 INT16=3\nuint8 UINT16=4\nuint8 INT32=5\nuint8 UINT32=6\nuint8 FLOAT32=7\nuint8 FLOAT64=8\nstring name\nuint32 offset\nuint8 datatype\nuint32 count\n"
);
msg!(
    POINT_CLOUD2,
    "sensor_msgs/msg/PointCloud2",
    [HEADER, POINT_FIELD],
    "std_msgs/Header header\nuint32 height\nuint32 width\nPointField[] fields\nbool is_bigendian\nuint32 point_step\nuint32 row_step\nuint8[] data\nbool is_dense\n"
);
msg!(
    MAP_META_DATA,
    "nav_msgs/msg/MapMetaData",
    [TIME, POSE],
    "builtin_interfaces/Time map_load_time\nfloat32 resolution\nuint32 width\nuint32 height\ngeometry_msgs/Pose origin\n"
);
msg!(
    OCCUPANCY_GRID,
    "nav_msgs/msg/OccupancyGrid",
    [HEADER, MAP_META_DATA],
    "std_msgs/Header header\nMapMetaData info\nint8[] data\n"
);
msg!(
    PATH,
    "nav_msgs/msg/Path",
    [HEADER, POSE_STAMPED],
    "std_msgs/Header header\ngeometry_msgs/PoseStamped[] poses\n"
);
msg!(
    COLOR_RGBA,
    "std_msgs/msg/ColorRGBA",
    [],
    "float32 r\nfloat32 g\nfloat32 b\nfloat32 a\n"
);
msg!(
    COMPRESSED_IMAGE,
    "sensor_msgs/msg/CompressedImage",
    [HEADER],
    "std_msgs/Header header\nstring format\nuint8[] data\n"
);
msg!(
    UV_COORDINATE,
    "visualization_msgs/msg/UVCoordinate",
    [],
    "float32 u\nfloat32 v\n"
);
msg!(
    MESH_FILE,
    "visualization_msgs/msg/MeshFile",
    [],
    "string filename\nuint8[] data\n"
);
msg!(
    MARKER,
    "visualization_msgs/msg/Marker",
    [HEADER, POSE, VECTOR3, COLOR_RGBA, DURATION, POINT, COMPRESSED_IMAGE, UV_COORDINATE, MESH_FILE],
    "int32 ARROW=0\nint32 CUBE=1\nint32 SPHERE=2\nint32 CYLINDER=3\nint32 LINE_STRIP=4\nint32 LINE_LIST=5\nint32 CUBE_LIST=6\nint32 SPHERE_LIST=7\nint32 POINTS=8\nint32 TEXT_VIEW_FACING=9\nint32 MESH_RESOURCE=10\nint32 TRIANGLE_LIST=11\nint32 ARROW_STRIP=12\nint32 ADD=0\nint32 MODIFY=0\nint32 DELETE=2\nint32 DELETEALL=3\nstd_msgs/Header header\nstring ns\nint32 id\nint32 type\nint32 action\ngeometry_msgs/Pose pose\ngeometry_msgs/Vector3 scale\nstd_msgs/ColorRGBA color\nbuiltin_interfaces/Duration lifetime\nbool frame_locked\ngeometry_msgs/Point[] points\nstd_msgs/ColorRGBA[] colors\nstring texture_resource\nsensor_msgs/CompressedImage texture\nvisualization_msgs/UVCoordinate[] uv_coordinates\nstring text\nstring mesh_resource\nvisualization_msgs/MeshFile mesh_file\nbool mesh_use_embedded_materials\n"
);
msg!(
    MARKER_ARRAY,
    "visualization_msgs/msg/MarkerArray",
    [MARKER],
    "Marker[] markers\n"
);
msg!(
    LOG,
    "rcl_interfaces/msg/Log",
    [TIME],
    "byte DEBUG=10\nbyte INFO=20\nbyte WARN=30\nbyte ERROR=40\nbyte FATAL=50\nbuiltin_interfaces/Time stamp\nuint8 level\nstring name\nstring msg\nstring file\nstring function\nuint32 line\n"
);

msg!(
    FERROBOT_COMMAND,
    "ferrobot_msgs/msg/Command",
    [],
    "string kind\nuint8[] postcard\n"
);

/// Every message type here.
pub const ALL: [&MsgType; 37] = [
    &TIME,
    &CLOCK,
    &DURATION,
    &HEADER,
    &STRING,
    &INT8,
    &VECTOR3,
    &POINT,
    &QUATERNION,
    &POSE,
    &POSE_STAMPED,
    &POSE_WITH_COVARIANCE,
    &TWIST,
    &TWIST_WITH_COVARIANCE,
    &TRANSFORM,
    &TRANSFORM_STAMPED,
    &TF_MESSAGE,
    &JOINT_STATE,
    &IMAGE,
    &REGION_OF_INTEREST,
    &CAMERA_INFO,
    &ODOMETRY,
    &JOINT_TRAJECTORY_POINT,
    &JOINT_TRAJECTORY,
    &POINT_FIELD,
    &POINT_CLOUD2,
    &MAP_META_DATA,
    &OCCUPANCY_GRID,
    &PATH,
    &COLOR_RGBA,
    &COMPRESSED_IMAGE,
    &UV_COORDINATE,
    &MESH_FILE,
    &MARKER,
    &MARKER_ARRAY,
    &LOG,
    &FERROBOT_COMMAND,
];

/// The separator rosbag2 writes between a definition and each type it uses.
const SEPARATOR: &str =
    "================================================================================\n";

impl MsgType {
    /// The schema text: the definition, then every type used (transitively, each once, in
    /// the order first met), each after the separator and `MSG: pkg/Type`.
    pub fn schema(&self) -> String {
        let mut seen: Vec<&'static str> = Vec::new();
        let mut order: Vec<&MsgType> = Vec::new();
        fn walk(t: &MsgType, seen: &mut Vec<&'static str>, order: &mut Vec<&'static MsgType>) {
            for &u in t.uses {
                if !seen.contains(&u.name) {
                    seen.push(u.name);
                    order.push(u);
                    walk(u, seen, order);
                }
            }
        }
        walk(self, &mut seen, &mut order);
        let mut s = self.definition.to_string();
        for t in order {
            s.push_str(SEPARATOR);
            s.push_str("MSG: ");
            s.push_str(&t.name.replacen("/msg/", "/", 1));
            s.push('\n');
            s.push_str(t.definition);
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_schema_lists_each_type_it_uses_once() {
        let s = ODOMETRY.schema();
        assert!(s.starts_with("std_msgs/Header header\n"));
        for t in [
            "std_msgs/Header",
            "builtin_interfaces/Time",
            "geometry_msgs/PoseWithCovariance",
            "geometry_msgs/Pose",
            "geometry_msgs/Point",
            "geometry_msgs/Quaternion",
            "geometry_msgs/TwistWithCovariance",
            "geometry_msgs/Twist",
            "geometry_msgs/Vector3",
        ] {
            assert_eq!(s.matches(&format!("MSG: {t}\n")).count(), 1, "{t}");
        }
        assert_eq!(STRING.schema(), "string data\n");
    }
}
