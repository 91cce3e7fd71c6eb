//! The topics of a recording: each one's name, its ROS 2 type and what it holds. One table for
//! the recorder, replay and the dataset export.

use crate::schemas::{self, MsgType};

/// A topic: its name and its message type.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Topic {
    /// The name, as ROS 2 writes it.
    pub name: &'static str,
    /// Its message type.
    pub msg: &'static MsgType,
}

macro_rules! topic {
    ($id:ident, $name:literal, $msg:ident, $doc:literal) => {
        #[doc = concat!("`", $name, "`: ", $doc)]
        pub const $id: Topic = Topic {
            name: $name,
            msg: &schemas::$msg,
        };
    };
}

topic!(
    ROBOT_DESCRIPTION,
    "/robot_description",
    STRING,
    "the robot's URDF, once at the start."
);
topic!(
    TF_STATIC,
    "/tf_static",
    TF_MESSAGE,
    "the URDF's fixed joints, once at the start."
);
topic!(
    TF,
    "/tf",
    TF_MESSAGE,
    "every moving joint's child in its parent, and the base in `odom`, at each telemetry report."
);
topic!(
    JOINT_STATES,
    "/joint_states",
    JOINT_STATE,
    "the joint table's positions (rad; m for a prismatic joint), velocities and efforts (N·m), at each telemetry report (100 Hz)."
);
topic!(
    ODOM,
    "/odom",
    ODOMETRY,
    "the wheel odometry of the base (`odom` to the URDF's root), at each telemetry report."
);
topic!(
    GRIPPER_STATE,
    "/gripper/state",
    INT8,
    "the gripper's state as PyRobot's code (-1 unknown, 0 open, 1 closing, 2 holding, 3 closed, 4 opening), at the start and at each change."
);
topic!(
    CMD_VEL,
    "/cmd_vel",
    TWIST,
    "each base velocity command (m/s forward, rad/s yaw)."
);
topic!(
    JOINT_COMMANDS,
    "/joint_commands",
    JOINT_TRAJECTORY,
    "each joint command: a trajectory knot (time from start: its duration) or a direct position, velocity or effort command."
);
topic!(
    GRIPPER_COMMAND,
    "/gripper/command",
    STRING,
    "each gripper command: `open`, `close` or `stop`."
);
topic!(
    ROSOUT,
    "/rosout",
    LOG,
    "faults, emergency stops, resumes, mode changes, link events and the firmware's fault flags as they change."
);
topic!(
    COLOR,
    "/camera/color/image_raw",
    IMAGE,
    "the camera's colour (`rgb8`)."
);
topic!(
    DEPTH,
    "/camera/aligned_depth_to_color/image_raw",
    IMAGE,
    "depth aligned to colour (`32FC1`, m along the optical axis; 0 invalid)."
);
topic!(
    CAMERA_INFO,
    "/camera/color/camera_info",
    CAMERA_INFO,
    "the colour camera's intrinsics, with each frame."
);
topic!(
    POINTS,
    "/camera/depth/color/points",
    POINT_CLOUD2,
    "the frame's valid depths as coloured points in the optical frame, every fourth pixel of every fourth row (served, not recorded: the recording holds the depth they come from)."
);
topic!(
    CAMERA_POSE,
    "/camera/pose",
    POSE_STAMPED,
    "the optical frame in `base_link` at each frame's capture, from the measured joints."
);
topic!(
    CAMERA_ODOM,
    "/camera/odom_pose",
    POSE_STAMPED,
    "the base's wheel odometry in `odom` carried to each frame's capture: what SLAM is fed with the frame."
);
topic!(
    COMMANDS,
    "/ferrobot/commands",
    FERROBOT_COMMAND,
    "every command the firmware acknowledged, exactly: its kind, and the message in the wire protocol's postcard encoding (what replay sends)."
);
topic!(
    CLOCK,
    "/clock",
    CLOCK,
    "the robot's clock (the firmware's, from its start) at each telemetry report: what a ROS 2 node with `use_sim_time` keeps time by (the bridge publishes it; recordings leave it out)."
);
topic!(
    SLAM_POSE,
    "/slam/pose",
    POSE_STAMPED,
    "SLAM's pose of the body in `map`, at each tracked frame."
);

topic!(
    ARM_PLANNED_PATH,
    "/arm/planned_path",
    PATH,
    "each motion the arm planned: its end effector's poses in the arm's base frame along the timed trajectory, every 50 ms, each stamped when it would be reached."
);
topic!(
    MAP,
    "/map",
    OCCUPANCY_GRID,
    "the navigation map in `map` (0 free, 100 occupied, -1 unknown), at the start and at each change, at most once a second (served, not recorded)."
);
topic!(
    SCENE_MARKERS,
    "/scene/markers",
    MARKER_ARRAY,
    "the simulated world's bodies (boxes, cylinders, spheres, capsules) in `odom` where the robot started, with their live poses, twice a second (served on the simulator, not recorded)."
);

topic!(
    GOAL_POSE,
    "/goal_pose",
    POSE_STAMPED,
    "a goal for the base (rviz2's \"2D Goal Pose\"): its pose in `odom`, or in `map` while SLAM runs (served robots subscribe)."
);
topic!(
    ARM_JOINT_TRAJECTORY,
    "/arm/joint_trajectory",
    JOINT_TRAJECTORY,
    "a trajectory for the arm: every arm joint named, the arm moved through its points in order, each a planned motion (served robots subscribe)."
);

/// The topics a camera frame is published on: a server reads (renders, on the simulator) the
/// camera's frames only while someone subscribes to one of them.
pub const CAMERA: [Topic; 6] = [COLOR, DEPTH, CAMERA_INFO, POINTS, CAMERA_POSE, CAMERA_ODOM];

/// Every topic, in the order of this table.
pub const ALL: [Topic; 24] = [
    ROBOT_DESCRIPTION,
    TF_STATIC,
    TF,
    JOINT_STATES,
    ODOM,
    GRIPPER_STATE,
    CMD_VEL,
    JOINT_COMMANDS,
    GRIPPER_COMMAND,
    ROSOUT,
    COLOR,
    DEPTH,
    CAMERA_INFO,
    POINTS,
    CAMERA_POSE,
    CAMERA_ODOM,
    COMMANDS,
    CLOCK,
    SLAM_POSE,
    ARM_PLANNED_PATH,
    MAP,
    SCENE_MARKERS,
    GOAL_POSE,
    ARM_JOINT_TRAJECTORY,
];

impl Topic {
    /// Whether the topic says what holds until said again (the URDF, the fixed transforms, the
    /// map, the world's bodies, the last plan): publishers keep its last message for late
    /// subscribers (ROS 2's transient local durability, a viewer's latched channel).
    pub fn latched(&self) -> bool {
        [
            ROBOT_DESCRIPTION.name,
            TF_STATIC.name,
            MAP.name,
            SCENE_MARKERS.name,
            ARM_PLANNED_PATH.name,
        ]
        .contains(&self.name)
    }
}

/// The odometry's frame.
pub const ODOM_FRAME: &str = "odom";
/// SLAM's map frame.
pub const MAP_FRAME: &str = "map";
