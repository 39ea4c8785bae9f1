//! The message types, by ROS package, with their descriptions.

use crate::cdr::{CdrError, CdrField, CdrReader, CdrWriter};
use crate::description::{FieldDescription as F, MessageDescription, Primitive as P};

/// Implements [`CdrField`] for a struct: its fields in declaration order.
macro_rules! cdr_struct {
    ($ty:ident { $($field:ident),+ $(,)? }) => {
        impl CdrField for $ty {
            fn write_cdr(&self, writer: &mut CdrWriter<'_>) {
                $(self.$field.write_cdr(writer);)+
            }
            fn read_cdr(reader: &mut CdrReader<'_>) -> Result<Self, CdrError> {
                Ok(Self { $($field: CdrField::read_cdr(reader)?,)+ })
            }
        }
    };
}

/// Implements [`crate::RosMessage`] for a struct with its description.
macro_rules! ros_message {
    ($ty:ident, $description:ident) => {
        impl crate::RosMessage for $ty {
            const DESCRIPTION: &'static MessageDescription = &$description;
        }
    };
}

// ---------------------------------------------------------------- builtin_interfaces

/// `builtin_interfaces/msg/Time`: seconds and nanoseconds since the clock's epoch.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Time {
    /// Whole seconds.
    pub sec: i32,
    /// Nanoseconds within the second, `0..1e9`.
    pub nanosec: u32,
}

impl Time {
    /// From nanoseconds since the epoch (the node's clock); seconds past `i32::MAX` saturate.
    pub fn from_ns(ns: u64) -> Self {
        Self {
            sec: i32::try_from(ns / 1_000_000_000).unwrap_or(i32::MAX),
            nanosec: (ns % 1_000_000_000) as u32,
        }
    }

    /// Back to nanoseconds (negative times are 0).
    pub fn as_ns(self) -> u64 {
        u64::try_from(self.sec).unwrap_or(0) * 1_000_000_000 + u64::from(self.nanosec)
    }
}
cdr_struct!(Time { sec, nanosec });
ros_message!(Time, TIME);

/// Description of [`Time`].
pub static TIME: MessageDescription = MessageDescription {
    type_name: "builtin_interfaces/msg/Time",
    msg_text: "int32 sec\nuint32 nanosec\n",
    fields: &[
        F::primitive("sec", P::Int32),
        F::primitive("nanosec", P::Uint32),
    ],
};

// ---------------------------------------------------------------- std_msgs

/// `std_msgs/msg/Header`: when and in which frame.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Header {
    /// The time of the data.
    pub stamp: Time,
    /// The frame the data is expressed in.
    pub frame_id: String,
}
cdr_struct!(Header { stamp, frame_id });
ros_message!(Header, HEADER);

/// Description of [`Header`].
pub static HEADER: MessageDescription = MessageDescription {
    type_name: "std_msgs/msg/Header",
    msg_text: "builtin_interfaces/Time stamp\nstring frame_id\n",
    fields: &[
        F::nested("stamp", &TIME),
        F::primitive("frame_id", P::String),
    ],
};

// ---------------------------------------------------------------- geometry_msgs

/// `geometry_msgs/msg/Point` (m).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Point {
    /// x
    pub x: f64,
    /// y
    pub y: f64,
    /// z
    pub z: f64,
}
cdr_struct!(Point { x, y, z });
ros_message!(Point, POINT);

/// Description of [`Point`].
pub static POINT: MessageDescription = MessageDescription {
    type_name: "geometry_msgs/msg/Point",
    msg_text: "float64 x\nfloat64 y\nfloat64 z\n",
    fields: &[
        F::primitive("x", P::Float64),
        F::primitive("y", P::Float64),
        F::primitive("z", P::Float64),
    ],
};

/// `geometry_msgs/msg/Quaternion` (x, y, z, w); the default is the identity.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Quaternion {
    /// x
    pub x: f64,
    /// y
    pub y: f64,
    /// z
    pub z: f64,
    /// w
    pub w: f64,
}

impl Default for Quaternion {
    fn default() -> Self {
        Self {
            x: 0.0,
            y: 0.0,
            z: 0.0,
            w: 1.0,
        }
    }
}
cdr_struct!(Quaternion { x, y, z, w });
ros_message!(Quaternion, QUATERNION);

/// Description of [`Quaternion`].
pub static QUATERNION: MessageDescription = MessageDescription {
    type_name: "geometry_msgs/msg/Quaternion",
    msg_text: "float64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1\n",
    fields: &[
        F::primitive("x", P::Float64),
        F::primitive("y", P::Float64),
        F::primitive("z", P::Float64),
        F::primitive("w", P::Float64),
    ],
};

/// `geometry_msgs/msg/Vector3`.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Vector3 {
    /// x
    pub x: f64,
    /// y
    pub y: f64,
    /// z
    pub z: f64,
}
cdr_struct!(Vector3 { x, y, z });
ros_message!(Vector3, VECTOR3);

/// Description of [`Vector3`].
pub static VECTOR3: MessageDescription = MessageDescription {
    type_name: "geometry_msgs/msg/Vector3",
    msg_text: "float64 x\nfloat64 y\nfloat64 z\n",
    fields: &[
        F::primitive("x", P::Float64),
        F::primitive("y", P::Float64),
        F::primitive("z", P::Float64),
    ],
};

/// `geometry_msgs/msg/Pose`.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Pose {
    /// Position (m).
    pub position: Point,
    /// Orientation.
    pub orientation: Quaternion,
}
cdr_struct!(Pose {
    position,
    orientation
});
ros_message!(Pose, POSE);

/// Description of [`Pose`].
pub static POSE: MessageDescription = MessageDescription {
    type_name: "geometry_msgs/msg/Pose",
    msg_text: "Point position\nQuaternion orientation\n",
    fields: &[
        F::nested("position", &POINT),
        F::nested("orientation", &QUATERNION),
    ],
};

/// `geometry_msgs/msg/PoseStamped`.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PoseStamped {
    /// Time and frame.
    pub header: Header,
    /// The pose in `header.frame_id`.
    pub pose: Pose,
}
cdr_struct!(PoseStamped { header, pose });
ros_message!(PoseStamped, POSE_STAMPED);

/// Description of [`PoseStamped`].
pub static POSE_STAMPED: MessageDescription = MessageDescription {
    type_name: "geometry_msgs/msg/PoseStamped",
    msg_text: "std_msgs/Header header\nPose pose\n",
    fields: &[F::nested("header", &HEADER), F::nested("pose", &POSE)],
};

/// `geometry_msgs/msg/Wrench` (N, N·m).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Wrench {
    /// Force (N).
    pub force: Vector3,
    /// Torque (N·m).
    pub torque: Vector3,
}
cdr_struct!(Wrench { force, torque });
ros_message!(Wrench, WRENCH);

/// Description of [`Wrench`].
pub static WRENCH: MessageDescription = MessageDescription {
    type_name: "geometry_msgs/msg/Wrench",
    msg_text: "Vector3 force\nVector3 torque\n",
    fields: &[F::nested("force", &VECTOR3), F::nested("torque", &VECTOR3)],
};

/// `geometry_msgs/msg/WrenchStamped`.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct WrenchStamped {
    /// Time and frame.
    pub header: Header,
    /// The wrench in `header.frame_id`.
    pub wrench: Wrench,
}
cdr_struct!(WrenchStamped { header, wrench });
ros_message!(WrenchStamped, WRENCH_STAMPED);

/// Description of [`WrenchStamped`].
pub static WRENCH_STAMPED: MessageDescription = MessageDescription {
    type_name: "geometry_msgs/msg/WrenchStamped",
    msg_text: "std_msgs/Header header\nWrench wrench\n",
    fields: &[F::nested("header", &HEADER), F::nested("wrench", &WRENCH)],
};

/// `geometry_msgs/msg/Transform`.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Transform {
    /// Translation (m).
    pub translation: Vector3,
    /// Rotation.
    pub rotation: Quaternion,
}
cdr_struct!(Transform {
    translation,
    rotation
});
ros_message!(Transform, TRANSFORM);

/// Description of [`Transform`].
pub static TRANSFORM: MessageDescription = MessageDescription {
    type_name: "geometry_msgs/msg/Transform",
    msg_text: "Vector3 translation\nQuaternion rotation\n",
    fields: &[
        F::nested("translation", &VECTOR3),
        F::nested("rotation", &QUATERNION),
    ],
};

/// `geometry_msgs/msg/TransformStamped`: the pose of `child_frame_id` in `header.frame_id`.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TransformStamped {
    /// Time and parent frame.
    pub header: Header,
    /// The child frame.
    pub child_frame_id: String,
    /// The child's pose in the parent.
    pub transform: Transform,
}
cdr_struct!(TransformStamped {
    header,
    child_frame_id,
    transform
});
ros_message!(TransformStamped, TRANSFORM_STAMPED);

/// Description of [`TransformStamped`].
pub static TRANSFORM_STAMPED: MessageDescription = MessageDescription {
    type_name: "geometry_msgs/msg/TransformStamped",
    msg_text: "std_msgs/Header header\nstring child_frame_id\nTransform transform\n",
    fields: &[
        F::nested("header", &HEADER),
        F::primitive("child_frame_id", P::String),
        F::nested("transform", &TRANSFORM),
    ],
};

// ---------------------------------------------------------------- sensor_msgs

/// `sensor_msgs/msg/JointState`: per joint name, position (rad or m), velocity, effort
/// (N·m or N); a sequence may be empty when that quantity is unknown.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct JointState {
    /// Time (frame unused).
    pub header: Header,
    /// Joint names.
    pub name: Vec<String>,
    /// Positions.
    pub position: Vec<f64>,
    /// Velocities.
    pub velocity: Vec<f64>,
    /// Efforts.
    pub effort: Vec<f64>,
}
cdr_struct!(JointState {
    header,
    name,
    position,
    velocity,
    effort
});
ros_message!(JointState, JOINT_STATE);

/// Description of [`JointState`].
pub static JOINT_STATE: MessageDescription = MessageDescription {
    type_name: "sensor_msgs/msg/JointState",
    msg_text: "std_msgs/Header header\nstring[] name\nfloat64[] position\nfloat64[] velocity\nfloat64[] effort\n",
    fields: &[
        F::nested("header", &HEADER),
        F::primitive("name", P::String).sequence(),
        F::primitive("position", P::Float64).sequence(),
        F::primitive("velocity", P::Float64).sequence(),
        F::primitive("effort", P::Float64).sequence(),
    ],
};

/// `sensor_msgs/msg/Joy`: a joystick's axes and buttons.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Joy {
    /// Time of the reading.
    pub header: Header,
    /// Axes, each usually in -1..1.
    pub axes: Vec<f32>,
    /// Buttons, 0 or 1.
    pub buttons: Vec<i32>,
}
cdr_struct!(Joy {
    header,
    axes,
    buttons
});
ros_message!(Joy, JOY);

/// Description of [`Joy`].
pub static JOY: MessageDescription = MessageDescription {
    type_name: "sensor_msgs/msg/Joy",
    msg_text: "std_msgs/Header header\nfloat32[] axes\nint32[] buttons\n",
    fields: &[
        F::nested("header", &HEADER),
        F::primitive("axes", P::Float32).sequence(),
        F::primitive("buttons", P::Int32).sequence(),
    ],
};

/// `sensor_msgs/msg/CompressedImage`: an encoded image (`format`: `"jpeg"`), stamped with its
/// capture instant, in the camera's optical frame.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct CompressedImage {
    /// Capture instant and the camera's optical frame.
    pub header: Header,
    /// The encoding: `"jpeg"`, `"png"`.
    pub format: String,
    /// The encoded image.
    pub data: Vec<u8>,
}
cdr_struct!(CompressedImage {
    header,
    format,
    data
});
ros_message!(CompressedImage, COMPRESSED_IMAGE);

/// Description of [`CompressedImage`].
pub static COMPRESSED_IMAGE: MessageDescription = MessageDescription {
    type_name: "sensor_msgs/msg/CompressedImage",
    msg_text: "std_msgs/Header header\nstring format\nuint8[] data\n",
    fields: &[
        F::nested("header", &HEADER),
        F::primitive("format", P::String),
        F::primitive("data", P::Uint8).sequence(),
    ],
};

/// `sensor_msgs/msg/RegionOfInterest`: a part of an image (all zero: the whole image).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct RegionOfInterest {
    /// Leftmost pixel.
    pub x_offset: u32,
    /// Topmost pixel.
    pub y_offset: u32,
    /// Height, px.
    pub height: u32,
    /// Width, px.
    pub width: u32,
    /// Whether the region is to be rectified.
    pub do_rectify: bool,
}
cdr_struct!(RegionOfInterest {
    x_offset,
    y_offset,
    height,
    width,
    do_rectify
});
ros_message!(RegionOfInterest, REGION_OF_INTEREST);

/// Description of [`RegionOfInterest`].
pub static REGION_OF_INTEREST: MessageDescription = MessageDescription {
    type_name: "sensor_msgs/msg/RegionOfInterest",
    msg_text: "uint32 x_offset\nuint32 y_offset\nuint32 height\nuint32 width\nbool do_rectify\n",
    fields: &[
        F::primitive("x_offset", P::Uint32),
        F::primitive("y_offset", P::Uint32),
        F::primitive("height", P::Uint32),
        F::primitive("width", P::Uint32),
        F::primitive("do_rectify", P::Bool),
    ],
};

/// `sensor_msgs/msg/CameraInfo`: a camera's calibration, what `image_geometry` projects
/// with: the intrinsic matrix `k`, the rectification `r` and the projection `p` (row-major).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct CameraInfo {
    /// Time and the camera's optical frame.
    pub header: Header,
    /// Image height, px.
    pub height: u32,
    /// Image width, px.
    pub width: u32,
    /// `"plumb_bob"`, `"rational_polynomial"`, ...
    pub distortion_model: String,
    /// The distortion coefficients (empty or zeros: none).
    pub d: Vec<f64>,
    /// The intrinsic matrix `[fx 0 cx; 0 fy cy; 0 0 1]`.
    pub k: [f64; 9],
    /// The rectification rotation (identity for a monocular camera).
    pub r: [f64; 9],
    /// The projection matrix `[fx' 0 cx' tx; 0 fy' cy' ty; 0 0 1 0]`.
    pub p: [f64; 12],
    /// Horizontal binning.
    pub binning_x: u32,
    /// Vertical binning.
    pub binning_y: u32,
    /// The region of the full image this one is.
    pub roi: RegionOfInterest,
}
cdr_struct!(CameraInfo {
    header,
    height,
    width,
    distortion_model,
    d,
    k,
    r,
    p,
    binning_x,
    binning_y,
    roi
});
ros_message!(CameraInfo, CAMERA_INFO);

impl CameraInfo {
    /// An ideal pinhole camera (no distortion, no rectification, no binning) of `width` x
    /// `height` px with focal lengths `fx`, `fy` and principal point `cx`, `cy` (px).
    pub fn pinhole(header: Header, width: u32, height: u32, f: [f64; 2], c: [f64; 2]) -> Self {
        let ([fx, fy], [cx, cy]) = (f, c);
        CameraInfo {
            header,
            height,
            width,
            distortion_model: "plumb_bob".into(),
            d: vec![0.0; 5],
            k: [fx, 0.0, cx, 0.0, fy, cy, 0.0, 0.0, 1.0],
            r: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
            p: [fx, 0.0, cx, 0.0, 0.0, fy, cy, 0.0, 0.0, 0.0, 1.0, 0.0],
            binning_x: 0,
            binning_y: 0,
            roi: RegionOfInterest::default(),
        }
    }
}

/// Description of [`CameraInfo`].
pub static CAMERA_INFO: MessageDescription = MessageDescription {
    type_name: "sensor_msgs/msg/CameraInfo",
    msg_text: "std_msgs/Header header\nuint32 height\nuint32 width\nstring distortion_model\nfloat64[] d\nfloat64[9] k\nfloat64[9] r\nfloat64[12] p\nuint32 binning_x\nuint32 binning_y\nRegionOfInterest roi\n",
    fields: &[
        F::nested("header", &HEADER),
        F::primitive("height", P::Uint32),
        F::primitive("width", P::Uint32),
        F::primitive("distortion_model", P::String),
        F::primitive("d", P::Float64).sequence(),
        F::primitive("k", P::Float64).array(9),
        F::primitive("r", P::Float64).array(9),
        F::primitive("p", P::Float64).array(12),
        F::primitive("binning_x", P::Uint32),
        F::primitive("binning_y", P::Uint32),
        F::nested("roi", &REGION_OF_INTEREST),
    ],
};

// ---------------------------------------------------------------- tf2_msgs

/// `tf2_msgs/msg/TFMessage`: a batch of transforms (the `/tf` topic).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TFMessage {
    /// The transforms.
    pub transforms: Vec<TransformStamped>,
}
cdr_struct!(TFMessage { transforms });
ros_message!(TFMessage, TF_MESSAGE);

/// Description of [`TFMessage`].
pub static TF_MESSAGE: MessageDescription = MessageDescription {
    type_name: "tf2_msgs/msg/TFMessage",
    msg_text: "geometry_msgs/TransformStamped[] transforms\n",
    fields: &[F::nested("transforms", &TRANSFORM_STAMPED).sequence()],
};

// ---------------------------------------------------------------- diagnostic_msgs

/// `diagnostic_msgs/msg/KeyValue`.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct KeyValue {
    /// The figure's name.
    pub key: String,
    /// Its value, as text.
    pub value: String,
}
cdr_struct!(KeyValue { key, value });
ros_message!(KeyValue, KEY_VALUE);

/// Description of [`KeyValue`].
pub static KEY_VALUE: MessageDescription = MessageDescription {
    type_name: "diagnostic_msgs/msg/KeyValue",
    msg_text: "string key\nstring value\n",
    fields: &[
        F::primitive("key", P::String),
        F::primitive("value", P::String),
    ],
};

/// `diagnostic_msgs/msg/DiagnosticStatus`: one component's state.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct DiagnosticStatus {
    /// [`DiagnosticStatus::OK`], [`DiagnosticStatus::WARN`], [`DiagnosticStatus::ERROR`] or
    /// [`DiagnosticStatus::STALE`].
    pub level: u8,
    /// The component's name.
    pub name: String,
    /// A human-readable summary.
    pub message: String,
    /// The hardware it runs on (may be empty).
    pub hardware_id: String,
    /// The figures.
    pub values: Vec<KeyValue>,
}

impl DiagnosticStatus {
    /// Level: all well.
    pub const OK: u8 = 0;
    /// Level: working, with a problem (losses).
    pub const WARN: u8 = 1;
    /// Level: not working (down).
    pub const ERROR: u8 = 2;
    /// Level: no recent information.
    pub const STALE: u8 = 3;
}
cdr_struct!(DiagnosticStatus {
    level,
    name,
    message,
    hardware_id,
    values
});
ros_message!(DiagnosticStatus, DIAGNOSTIC_STATUS);

/// Description of [`DiagnosticStatus`].
pub static DIAGNOSTIC_STATUS: MessageDescription = MessageDescription {
    type_name: "diagnostic_msgs/msg/DiagnosticStatus",
    msg_text: "byte OK=0\nbyte WARN=1\nbyte ERROR=2\nbyte STALE=3\nbyte level\nstring name\nstring message\nstring hardware_id\nKeyValue[] values\n",
    fields: &[
        F::primitive("level", P::Byte),
        F::primitive("name", P::String),
        F::primitive("message", P::String),
        F::primitive("hardware_id", P::String),
        F::nested("values", &KEY_VALUE).sequence(),
    ],
};

/// `diagnostic_msgs/msg/DiagnosticArray` (the `/diagnostics` topic).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct DiagnosticArray {
    /// Time.
    pub header: Header,
    /// One status per component.
    pub status: Vec<DiagnosticStatus>,
}
cdr_struct!(DiagnosticArray { header, status });
ros_message!(DiagnosticArray, DIAGNOSTIC_ARRAY);

/// Description of [`DiagnosticArray`].
pub static DIAGNOSTIC_ARRAY: MessageDescription = MessageDescription {
    type_name: "diagnostic_msgs/msg/DiagnosticArray",
    msg_text: "std_msgs/Header header\nDiagnosticStatus[] status\n",
    fields: &[
        F::nested("header", &HEADER),
        F::nested("status", &DIAGNOSTIC_STATUS).sequence(),
    ],
};

// ---------------------------------------------------------------- crtk_msgs

/// `crtk_msgs/msg/OperatingState`: a CRTK device's state (`DISABLED`, `ENABLED`, `PAUSED`,
/// `FAULT`), whether it is homed and whether it is busy.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct OperatingState {
    /// Time.
    pub header: Header,
    /// One of [`OperatingState::DISABLED`], [`OperatingState::ENABLED`],
    /// [`OperatingState::PAUSED`], [`OperatingState::FAULT`].
    pub state: String,
    /// Whether the device knows its joints' positions.
    pub is_homed: bool,
    /// Whether it is executing a motion it was asked for.
    pub is_busy: bool,
}

impl OperatingState {
    /// CRTK state: not powered / not accepting commands.
    pub const DISABLED: &'static str = "DISABLED";
    /// CRTK state: powered, accepting commands.
    pub const ENABLED: &'static str = "ENABLED";
    /// CRTK state: powered, holding, not moving.
    pub const PAUSED: &'static str = "PAUSED";
    /// CRTK state: stopped by a fault.
    pub const FAULT: &'static str = "FAULT";
}
cdr_struct!(OperatingState {
    header,
    state,
    is_homed,
    is_busy
});
ros_message!(OperatingState, OPERATING_STATE);

/// Description of [`OperatingState`].
pub static OPERATING_STATE: MessageDescription = MessageDescription {
    type_name: "crtk_msgs/msg/OperatingState",
    msg_text: "std_msgs/Header header\nstring state\nbool is_homed\nbool is_busy\n",
    fields: &[
        F::nested("header", &HEADER),
        F::primitive("state", P::String),
        F::primitive("is_homed", P::Bool),
        F::primitive("is_busy", P::Bool),
    ],
};

/// Every message type this crate has, for tools and tests that go over them all.
pub static ALL_TYPES: &[&MessageDescription] = &[
    &TIME,
    &HEADER,
    &POINT,
    &QUATERNION,
    &VECTOR3,
    &POSE,
    &POSE_STAMPED,
    &WRENCH,
    &WRENCH_STAMPED,
    &TRANSFORM,
    &TRANSFORM_STAMPED,
    &JOINT_STATE,
    &JOY,
    &COMPRESSED_IMAGE,
    &REGION_OF_INTEREST,
    &CAMERA_INFO,
    &TF_MESSAGE,
    &KEY_VALUE,
    &DIAGNOSTIC_STATUS,
    &DIAGNOSTIC_ARRAY,
    &OPERATING_STATE,
];
