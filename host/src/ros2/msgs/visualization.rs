//! `visualization_msgs/Marker(Array)`: the field, the beacons, the parts and the path as
//! rviz2 and Foxglove draw them.

use serde::{Deserialize, Serialize};

use super::geometry::{Point, Pose, Vector3};
use super::{ColorRgba, Duration, Header, RosMessage};

/// `sensor_msgs/msg/CompressedImage` (a marker's texture; ours are empty).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct CompressedImage {
    /// When and where.
    pub header: Header,
    /// `jpeg` or `png`.
    pub format: String,
    /// The image file's bytes.
    pub data: Vec<u8>,
}

/// `visualization_msgs/msg/UVCoordinate`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct UvCoordinate {
    /// u.
    pub u: f32,
    /// v.
    pub v: f32,
}

/// `visualization_msgs/msg/MeshFile`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct MeshFile {
    /// The file's name.
    pub filename: String,
    /// Its bytes.
    pub data: Vec<u8>,
}

/// `visualization_msgs/msg/Marker` (Jazzy: with texture and mesh file fields).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Marker {
    /// When and the frame `pose` is in.
    pub header: Header,
    /// Namespace: with `id`, what identifies the marker.
    pub ns: String,
    /// Identifier within `ns`.
    pub id: i32,
    /// [`Marker::CUBE`], [`Marker::CYLINDER`], [`Marker::LINE_STRIP`], ...
    #[serde(rename = "type")]
    pub kind: i32,
    /// [`Marker::ADD`] or [`Marker::DELETEALL`].
    pub action: i32,
    /// The shape's pose.
    pub pose: Pose,
    /// Size, m (a line's width in `x`).
    pub scale: Vector3,
    /// Colour.
    pub color: ColorRgba,
    /// How long it stays (0: until replaced).
    pub lifetime: Duration,
    /// Redrawn in its frame as that frame moves.
    pub frame_locked: bool,
    /// A line's or a list's points, in the marker's frame.
    pub points: Vec<Point>,
    /// Per-point colours (empty: `color`).
    pub colors: Vec<ColorRgba>,
    /// Texture URI (unused).
    pub texture_resource: String,
    /// Texture (unused).
    pub texture: CompressedImage,
    /// Texture coordinates (unused).
    pub uv_coordinates: Vec<UvCoordinate>,
    /// Text of a text marker.
    pub text: String,
    /// Mesh URI (unused).
    pub mesh_resource: String,
    /// Mesh (unused).
    pub mesh_file: MeshFile,
    /// Use the mesh's materials (unused).
    pub mesh_use_embedded_materials: bool,
}

impl Marker {
    /// A box.
    pub const CUBE: i32 = 1;
    /// A ball.
    pub const SPHERE: i32 = 2;
    /// An upright cylinder.
    pub const CYLINDER: i32 = 3;
    /// A polyline through `points`.
    pub const LINE_STRIP: i32 = 4;
    /// Text facing the viewer.
    pub const TEXT_VIEW_FACING: i32 = 9;
    /// Add or replace.
    pub const ADD: i32 = 0;
    /// Remove every marker of the namespace (rviz2: every marker).
    pub const DELETEALL: i32 = 3;
}

/// `visualization_msgs/msg/MarkerArray`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct MarkerArray {
    /// The markers.
    pub markers: Vec<Marker>,
}

impl RosMessage for MarkerArray {
    const TYPE_NAME: &'static str = "visualization_msgs/msg/MarkerArray";
}

#[cfg(test)]
mod tests {
    use super::super::{Time, hex, to_cdr};
    use super::*;

    #[test]
    fn an_empty_marker_lays_out_every_jazzy_field() {
        let array = MarkerArray {
            markers: vec![Marker {
                header: Header::new(Time { sec: 1, nanosec: 0 }, "m"),
                ns: "f".into(),
                id: 7,
                kind: Marker::CUBE,
                action: Marker::ADD,
                pose: Pose::default(),
                scale: Vector3 {
                    x: 1.0,
                    y: 1.0,
                    z: 1.0,
                },
                color: ColorRgba::rgb(1.0, 0.0, 0.0),
                ..Marker::default()
            }],
        };
        let one = "000000000000f03f";
        let zero = "0000000000000000";
        let expected = [
            "00010000", "01000000", // markers
            "01000000", "00000000", "02000000", "6d00", // header, "m" → 18
            "0000", "02000000", "6600", // ns → 26
            "0000", "07000000", "01000000",
            "00000000", // id, type, action → 40, aligned for the doubles
            zero, zero, zero, zero, zero, zero, one, // pose → 96
            one, one, one, // scale → 120
            "0000803f", "00000000", "00000000", "0000803f", // colour → 136
            "00000000", "00000000", // lifetime → 144
            "00",       // frame_locked → 145
            "000000", "00000000", // points → 152
            "00000000", // colors → 156
            "01000000", "00", // texture_resource → 161
            "000000", "00000000", "00000000", "01000000", "00", // texture header → 177
            "000000", "01000000", "00", // format → 185
            "000000", "00000000", // data → 192
            "00000000", // uv → 196
            "01000000", "00", // text → 201
            "000000", "01000000", "00", // mesh_resource → 209
            "000000", "01000000", "00", // filename → 217
            "000000", "00000000", // data → 224
            "00",       // mesh_use_embedded_materials
        ]
        .concat();
        assert_eq!(hex(&to_cdr(&array).unwrap()), expected);
    }
}
