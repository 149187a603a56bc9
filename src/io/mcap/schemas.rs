//! Schema records written into MCAP files: `(name, encoding, data)`.

/// `foxglove.PointCloud` (protobuf FileDescriptorSet).
pub const FOXGLOVE_POINT_CLOUD: (&str, &str, &[u8]) = (
    "foxglove.PointCloud",
    "protobuf",
    include_bytes!("schemas/foxglove.PointCloud.fds.bin"),
);
/// `foxglove.PosesInFrame`.
pub const FOXGLOVE_POSES_IN_FRAME: (&str, &str, &[u8]) = (
    "foxglove.PosesInFrame",
    "protobuf",
    include_bytes!("schemas/foxglove.PosesInFrame.fds.bin"),
);
/// `foxglove.PoseInFrame`.
pub const FOXGLOVE_POSE_IN_FRAME: (&str, &str, &[u8]) = (
    "foxglove.PoseInFrame",
    "protobuf",
    include_bytes!("schemas/foxglove.PoseInFrame.fds.bin"),
);
/// `foxglove.FrameTransform`.
pub const FOXGLOVE_FRAME_TRANSFORM: (&str, &str, &[u8]) = (
    "foxglove.FrameTransform",
    "protobuf",
    include_bytes!("schemas/foxglove.FrameTransform.fds.bin"),
);

/// `foxglove.SceneUpdate` (the occupancy map as cube primitives).
pub const FOXGLOVE_SCENE_UPDATE: (&str, &str, &[u8]) = (
    "foxglove.SceneUpdate",
    "protobuf",
    include_bytes!("schemas/foxglove.SceneUpdate.fds.bin"),
);

macro_rules! ros1 {
    ($name:expr, $text:expr) => {
        ($name, "ros1msg", $text.as_bytes())
    };
}

/// `lsd_slam_viewer/keyframeMsg`.
pub const ROS1_KEYFRAME: (&str, &str, &[u8]) = ros1!(
    "lsd_slam_viewer/keyframeMsg",
    "int32 id\nfloat64 time\nbool isKeyframe\n\n# camToWorld as serialization of sophus sim(3).\n\
     # may change with keyframeGraph-updates.\nfloat32[7] camToWorld\n\n\
     # camera parameter (fx fy cx cy), width, height\n# will never change, but required for display.\n\
     float32 fx\nfloat32 fy\nfloat32 cx\nfloat32 cy\nuint32 height\nuint32 width\n\n\
     # data as InputPointDense (float idepth, float idepth_var, uchar color[4]), width x height\n\
     # may be empty, in that case no associated pointcloud is ever shown.\nuint8[] pointcloud\n"
);

/// `lsd_slam_viewer/keyframeGraphMsg`.
pub const ROS1_KEYFRAME_GRAPH: (&str, &str, &[u8]) = ros1!(
    "lsd_slam_viewer/keyframeGraphMsg",
    "# data as serialization of sim(3)'s: (int id, float[7] camToWorld)\nuint32 numFrames\n\
     uint8[] frameData\n\n# constraints (int from, int to, float err)\nuint32 numConstraints\n\
     uint8[] constraintsData\n"
);

/// `geometry_msgs/PoseStamped` with its dependencies.
pub const ROS1_POSE_STAMPED: (&str, &str, &[u8]) = (
    "geometry_msgs/PoseStamped",
    "ros1msg",
    const_str_concat::POSE_STAMPED.as_bytes(),
);

/// `sensor_msgs/Imu` with its dependencies.
pub const ROS1_IMU: (&str, &str, &[u8]) = (
    "sensor_msgs/Imu",
    "ros1msg",
    const_str_concat::IMU.as_bytes(),
);

/// `sensor_msgs/msg/PointCloud2` (ROS 2) with its dependencies.
pub const ROS2_POINT_CLOUD2: (&str, &str, &[u8]) = (
    "sensor_msgs/msg/PointCloud2",
    "ros2msg",
    const_str_concat::POINT_CLOUD2.as_bytes(),
);

/// `tf2_msgs/msg/TFMessage` (ROS 2) with its dependencies.
pub const ROS2_TF_MESSAGE: (&str, &str, &[u8]) = (
    "tf2_msgs/msg/TFMessage",
    "ros2msg",
    const_str_concat::TF_MESSAGE.as_bytes(),
);

/// The concatenated definitions (written out: `concat!` needs literals).
mod const_str_concat {
    pub const POSE_STAMPED: &str = "Header header\nPose pose\n\
================================================================================\n\
MSG: std_msgs/Header\nuint32 seq\ntime stamp\nstring frame_id\n\
================================================================================\n\
MSG: geometry_msgs/Pose\nPoint position\nQuaternion orientation\n\
================================================================================\n\
MSG: geometry_msgs/Point\nfloat64 x\nfloat64 y\nfloat64 z\n\
================================================================================\n\
MSG: geometry_msgs/Quaternion\nfloat64 x\nfloat64 y\nfloat64 z\nfloat64 w\n";

    pub const IMU: &str = "Header header\ngeometry_msgs/Quaternion orientation\n\
float64[9] orientation_covariance\ngeometry_msgs/Vector3 angular_velocity\n\
float64[9] angular_velocity_covariance\ngeometry_msgs/Vector3 linear_acceleration\n\
float64[9] linear_acceleration_covariance\n\
================================================================================\n\
MSG: std_msgs/Header\nuint32 seq\ntime stamp\nstring frame_id\n\
================================================================================\n\
MSG: geometry_msgs/Quaternion\nfloat64 x\nfloat64 y\nfloat64 z\nfloat64 w\n\
================================================================================\n\
MSG: geometry_msgs/Vector3\nfloat64 x\nfloat64 y\nfloat64 z\n";

    pub const POINT_CLOUD2: &str = "std_msgs/Header header\nuint32 height\nuint32 width\n\
PointField[] fields\nbool is_bigendian\nuint32 point_step\nuint32 row_step\nuint8[] data\nbool is_dense\n\
================================================================================\n\
MSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id\n\
================================================================================\n\
MSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n\
================================================================================\n\
MSG: sensor_msgs/PointField\nuint8 INT8=1\nuint8 UINT8=2\nuint8 INT16=3\nuint8 UINT16=4\n\
uint8 INT32=5\nuint8 UINT32=6\nuint8 FLOAT32=7\nuint8 FLOAT64=8\nstring name\nuint32 offset\n\
uint8 datatype\nuint32 count\n";

    pub const TF_MESSAGE: &str = "geometry_msgs/TransformStamped[] transforms\n\
================================================================================\n\
MSG: geometry_msgs/TransformStamped\nstd_msgs/Header header\nstring child_frame_id\n\
Transform transform\n\
================================================================================\n\
MSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id\n\
================================================================================\n\
MSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n\
================================================================================\n\
MSG: geometry_msgs/Transform\nVector3 translation\nQuaternion rotation\n\
================================================================================\n\
MSG: geometry_msgs/Vector3\nfloat64 x\nfloat64 y\nfloat64 z\n\
================================================================================\n\
MSG: geometry_msgs/Quaternion\nfloat64 x\nfloat64 y\nfloat64 z\nfloat64 w\n";
}
