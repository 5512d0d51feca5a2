//! `sensor_msgs/msg/Imu` on the wire: its schema text checked against the
//! layout decoded here, and one message decoded from CDR (with the
//! `cdr-encoding` crate) into the stamp and the six axes.
//!
//! The schema text (`ros2msg`) lists the fields, then each dependency after a
//! line of `=` as `MSG: pkg/Name` (rosbag2) or `MSG: pkg/msg/Name` (other
//! writers); both are accepted, and field types are compared in the short form.

use byteorder::{BigEndian, LittleEndian};
use serde::Deserialize;

/// The names an Imu schema goes by.
pub const IMU_NAMES: [&str; 2] = ["sensor_msgs/msg/Imu", "sensor_msgs/Imu"];

/// The fields of `sensor_msgs/msg/Imu`, as (type, name), in order.
const IMU_FIELDS: [(&str, &str); 7] = [
    ("std_msgs/Header", "header"),
    ("geometry_msgs/Quaternion", "orientation"),
    ("float64[9]", "orientation_covariance"),
    ("geometry_msgs/Vector3", "angular_velocity"),
    ("float64[9]", "angular_velocity_covariance"),
    ("geometry_msgs/Vector3", "linear_acceleration"),
    ("float64[9]", "linear_acceleration_covariance"),
];

/// One Imu message: its `header.stamp` and the six axes (rad/s, m/s^2).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImuSample {
    /// `header.stamp`, ns since the epoch.
    pub stamp_ns: i64,
    /// angular_velocity x, y, z, then linear_acceleration x, y, z.
    pub axes: [f64; 6],
}

#[derive(Deserialize)]
struct Time {
    sec: i32,
    nanosec: u32,
}

#[derive(Deserialize)]
struct Header {
    stamp: Time,
    #[allow(dead_code)]
    frame_id: String,
}

#[derive(Deserialize)]
struct Vector3 {
    x: f64,
    y: f64,
    z: f64,
}

#[derive(Deserialize)]
#[allow(dead_code)]
struct Quaternion {
    x: f64,
    y: f64,
    z: f64,
    w: f64,
}

#[derive(Deserialize)]
#[allow(dead_code)]
struct Imu {
    header: Header,
    orientation: Quaternion,
    orientation_covariance: [f64; 9],
    angular_velocity: Vector3,
    angular_velocity_covariance: [f64; 9],
    linear_acceleration: Vector3,
    linear_acceleration_covariance: [f64; 9],
}

/// Decode one CDR message (its 4-byte encapsulation header first).
pub fn decode(data: &[u8]) -> Result<ImuSample, String> {
    if data.len() < 4 {
        return Err(format!("{} bytes: shorter than the CDR header", data.len()));
    }
    let body = &data[4..];
    let imu: Imu = match data[1] {
        0x01 => cdr_encoding::from_bytes::<Imu, LittleEndian>(body),
        0x00 => cdr_encoding::from_bytes::<Imu, BigEndian>(body),
        k => return Err(format!("CDR representation {:#04x} is not plain CDR", k)),
    }
    .map_err(|e| format!("not a sensor_msgs/msg/Imu in CDR: {e}"))?
    .0;
    let s = &imu.header.stamp;
    let w = &imu.angular_velocity;
    let a = &imu.linear_acceleration;
    Ok(ImuSample {
        stamp_ns: i64::from(s.sec) * 1_000_000_000 + i64::from(s.nanosec),
        axes: [w.x, w.y, w.z, a.x, a.y, a.z],
    })
}

/// `pkg/msg/Name` as `pkg/Name`; a bare `Header` as `std_msgs/Header`.
fn short_type(t: &str) -> String {
    if t == "Header" {
        return "std_msgs/Header".into();
    }
    match t.split('/').collect::<Vec<_>>()[..] {
        [pkg, "msg", name] => format!("{pkg}/{name}"),
        _ => t.to_string(),
    }
}

/// Check that a `ros2msg` schema text defines the Imu decoded here: the
/// top-level fields in order (comments and constants aside), and the
/// definitions of its nested types among the dependencies.
pub fn check_schema(text: &str) -> Result<(), String> {
    let mut sections = text.split("\n=").map(|s| s.trim_start_matches('='));
    let top = sections.next().unwrap_or("");
    let fields: Vec<(String, String)> = top
        .lines()
        .map(|l| l.split('#').next().unwrap_or("").trim())
        .filter(|l| !l.is_empty() && !l.contains('='))
        .filter_map(|l| {
            let mut it = l.split_whitespace();
            Some((short_type(it.next()?), it.next()?.to_string()))
        })
        .collect();
    let want: Vec<(String, String)> = IMU_FIELDS
        .iter()
        .map(|(t, n)| (t.to_string(), n.to_string()))
        .collect();
    if fields != want {
        let got: Vec<String> = fields.iter().map(|(t, n)| format!("{t} {n}")).collect();
        return Err(format!(
            "its fields are not those of sensor_msgs/msg/Imu: [{}]",
            got.join(", ")
        ));
    }
    let deps: Vec<String> = sections
        .filter_map(|s| {
            let l = s.lines().find(|l| l.trim_start().starts_with("MSG:"))?;
            Some(short_type(l.trim_start()["MSG:".len()..].trim()))
        })
        .collect();
    for need in ["std_msgs/Header", "geometry_msgs/Vector3"] {
        if !deps.iter().any(|d| d == need) {
            return Err(format!(
                "it does not define {need} (MSG: {need} or MSG: {})",
                need.replacen('/', "/msg/", 1)
            ));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    const SHORT: &str = "std_msgs/Header header\ngeometry_msgs/Quaternion orientation\n\
        float64[9] orientation_covariance # row major\ngeometry_msgs/Vector3 angular_velocity\n\
        float64[9] angular_velocity_covariance\ngeometry_msgs/Vector3 linear_acceleration\n\
        float64[9] linear_acceleration_covariance\n\
        ================================================================================\n\
        MSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id\n\
        ================================================================================\n\
        MSG: geometry_msgs/Vector3\nfloat64 x\nfloat64 y\nfloat64 z\n";

    #[test]
    fn both_dependency_forms_are_accepted() {
        check_schema(SHORT).unwrap();
        let long = SHORT
            .replace("MSG: std_msgs/Header", "MSG: std_msgs/msg/Header")
            .replace(
                "MSG: geometry_msgs/Vector3",
                "MSG: geometry_msgs/msg/Vector3",
            );
        check_schema(&long).unwrap();
        let e = check_schema(&SHORT.replace("angular_velocity\n", "angular_rate\n")).unwrap_err();
        assert!(e.contains("geometry_msgs/Vector3 angular_rate"), "{e}");
        let cut = &SHORT[..SHORT.find("====").unwrap()];
        let e = check_schema(cut).unwrap_err();
        assert!(e.contains("MSG: std_msgs/msg/Header"), "{e}");
    }

    /// A message laid out by hand as CDR (little- and big-endian): the
    /// stamp and the axes come back.
    #[test]
    fn decodes_hand_made_cdr() {
        for le in [true, false] {
            let mut b: Vec<u8> = vec![0, u8::from(le), 0, 0];
            let put32 = |b: &mut Vec<u8>, v: u32| {
                b.extend(if le { v.to_le_bytes() } else { v.to_be_bytes() })
            };
            put32(&mut b, 1_700_000_000); // sec
            put32(&mut b, 123_456_789); // nanosec
            put32(&mut b, 4); // frame_id: "imu" and its terminating null
            b.extend(b"imu\0");
            // doubles align to 8 from the body's start: 4 + 4 + 4 + 4 = 16, aligned
            let vals: Vec<f64> = (0..4 + 9 + 3 + 9 + 3 + 9).map(|i| i as f64 * 0.5).collect();
            for v in &vals {
                b.extend(if le { v.to_le_bytes() } else { v.to_be_bytes() });
            }
            let s = decode(&b).unwrap();
            assert_eq!(s.stamp_ns, 1_700_000_000_123_456_789);
            assert_eq!(s.axes, [6.5, 7.0, 7.5, 12.5, 13.0, 13.5]);
        }
        assert!(decode(&[0, 1, 0]).unwrap_err().contains("shorter"));
        assert!(decode(&[0, 1, 0, 0, 1, 2]).unwrap_err().contains("Imu"));
    }
}
