//! ROS 1 serialization: a bounds-checked reader, the messages the offline tools read
//! (`sensor_msgs/Imu`, `sensor_msgs/Temperature`) decoded into the ROS 2 side's types, and the
//! check of a connection's message definition against the layout decoded here.

use crate::ros2::{Header, Imu, Quaternion, Temperature, Time, Vector3};

/// Why ROS 1 message bytes could not be decoded. Offsets count from the message's first byte.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum Ros1Error {
    /// The message ends before a field does.
    #[error("message ends at byte {len} inside field `{field}` (needs bytes {offset}..{end})")]
    Truncated {
        /// The field being read.
        field: &'static str,
        /// Where the field starts.
        offset: usize,
        /// Where it would end.
        end: usize,
        /// The message length.
        len: usize,
    },
    /// A string is not UTF-8.
    #[error("field `{field}` at byte {offset} is not a UTF-8 string")]
    BadString {
        /// The field being read.
        field: &'static str,
        /// Where its length prefix starts.
        offset: usize,
    },
}

/// Reads one ROS 1 message field by field: little-endian, packed (no alignment). Never panics.
pub struct Ros1Reader<'a> {
    data: &'a [u8],
    pos: usize,
}

impl<'a> Ros1Reader<'a> {
    /// A reader on the message's first byte.
    pub fn new(data: &'a [u8]) -> Self {
        Self { data, pos: 0 }
    }

    fn take(&mut self, field: &'static str, n: usize) -> Result<&'a [u8], Ros1Error> {
        let end = self.pos.saturating_add(n);
        match self.data.get(self.pos..end) {
            Some(s) => {
                self.pos = end;
                Ok(s)
            }
            None => Err(Ros1Error::Truncated {
                field,
                offset: self.pos,
                end,
                len: self.data.len(),
            }),
        }
    }

    fn array<const N: usize>(&mut self, field: &'static str) -> Result<[u8; N], Ros1Error> {
        let mut out = [0u8; N];
        out.copy_from_slice(self.take(field, N)?);
        Ok(out)
    }

    /// Bytes not read yet.
    pub fn remaining(&self) -> usize {
        self.data.len().saturating_sub(self.pos)
    }

    /// Reads a `uint32`.
    pub fn u32(&mut self, field: &'static str) -> Result<u32, Ros1Error> {
        Ok(u32::from_le_bytes(self.array(field)?))
    }

    /// Reads a `float64`.
    pub fn f64(&mut self, field: &'static str) -> Result<f64, Ros1Error> {
        Ok(f64::from_le_bytes(self.array(field)?))
    }

    /// Reads a fixed-size `float64[N]` array (no count).
    pub fn f64_array<const N: usize>(
        &mut self,
        field: &'static str,
    ) -> Result<[f64; N], Ros1Error> {
        let mut out = [0.0; N];
        for v in &mut out {
            *v = self.f64(field)?;
        }
        Ok(out)
    }

    /// Reads a `string`: a `uint32` byte count, then the bytes (no NUL).
    pub fn string(&mut self, field: &'static str) -> Result<String, Ros1Error> {
        let offset = self.pos;
        let n = self.u32(field)? as usize;
        let bytes = self.take(field, n)?;
        String::from_utf8(bytes.to_vec()).map_err(|_| Ros1Error::BadString { field, offset })
    }

    /// Reads a `time`: `uint32` seconds and `uint32` nanoseconds since the Unix epoch.
    pub fn time(&mut self, field: &'static str) -> Result<Time, Ros1Error> {
        let sec = self.u32(field)?;
        let nsec = self.u32(field)?;
        Ok(Time::from_ns(
            u64::from(sec) * 1_000_000_000 + u64::from(nsec),
        ))
    }
}

/// A message type read from ROS 1 serialization.
pub trait Ros1Message: Sized {
    /// The ROS 1 type name (`sensor_msgs/Imu`).
    const TYPE: &'static str;
    /// The MD5 sum ROS 1 computes for the type: a connection announcing it has this layout.
    const MD5SUM: &'static str;
    /// The fields of the type and of every type it contains, by ROS 1 name (`Header` stands
    /// for `std_msgs/Header`), in declaration order: what a connection's message definition
    /// must say when its MD5 sum is not [`Self::MD5SUM`].
    const LAYOUT: &'static [(&'static str, &'static [(&'static str, &'static str)])];

    /// Reads the fields.
    fn read_ros1(r: &mut Ros1Reader<'_>) -> Result<Self, Ros1Error>;

    /// Decodes a whole message.
    fn from_ros1(data: &[u8]) -> Result<Self, Ros1Error> {
        Self::read_ros1(&mut Ros1Reader::new(data))
    }
}

const HEADER_FIELDS: &[(&str, &str)] =
    &[("uint32", "seq"), ("time", "stamp"), ("string", "frame_id")];
const VECTOR3_FIELDS: &[(&str, &str)] = &[("float64", "x"), ("float64", "y"), ("float64", "z")];
const QUATERNION_FIELDS: &[(&str, &str)] = &[
    ("float64", "x"),
    ("float64", "y"),
    ("float64", "z"),
    ("float64", "w"),
];

/// `std_msgs/Header` without its `seq`, which nothing downstream uses.
fn read_header(r: &mut Ros1Reader<'_>) -> Result<Header, Ros1Error> {
    r.u32("header.seq")?;
    Ok(Header {
        stamp: r.time("header.stamp")?,
        frame_id: r.string("header.frame_id")?,
    })
}

fn read_vector3(r: &mut Ros1Reader<'_>, field: &'static str) -> Result<Vector3, Ros1Error> {
    Ok(r.f64_array::<3>(field)?.into())
}

impl Ros1Message for Imu {
    const TYPE: &'static str = "sensor_msgs/Imu";
    const MD5SUM: &'static str = "6a62c6daae103f4ff57a132d6f95cec2";
    const LAYOUT: &'static [(&'static str, &'static [(&'static str, &'static str)])] = &[
        (
            "sensor_msgs/Imu",
            &[
                ("std_msgs/Header", "header"),
                ("geometry_msgs/Quaternion", "orientation"),
                ("float64[9]", "orientation_covariance"),
                ("geometry_msgs/Vector3", "angular_velocity"),
                ("float64[9]", "angular_velocity_covariance"),
                ("geometry_msgs/Vector3", "linear_acceleration"),
                ("float64[9]", "linear_acceleration_covariance"),
            ],
        ),
        ("std_msgs/Header", HEADER_FIELDS),
        ("geometry_msgs/Quaternion", QUATERNION_FIELDS),
        ("geometry_msgs/Vector3", VECTOR3_FIELDS),
    ];

    fn read_ros1(r: &mut Ros1Reader<'_>) -> Result<Self, Ros1Error> {
        let header = read_header(r)?;
        let [x, y, z, w] = r.f64_array::<4>("orientation")?;
        Ok(Self {
            header,
            orientation: Quaternion { x, y, z, w },
            orientation_covariance: r.f64_array("orientation_covariance")?,
            angular_velocity: read_vector3(r, "angular_velocity")?,
            angular_velocity_covariance: r.f64_array("angular_velocity_covariance")?,
            linear_acceleration: read_vector3(r, "linear_acceleration")?,
            linear_acceleration_covariance: r.f64_array("linear_acceleration_covariance")?,
        })
    }
}

impl Ros1Message for Temperature {
    const TYPE: &'static str = "sensor_msgs/Temperature";
    const MD5SUM: &'static str = "ff71b307acdbe7c871a5a6d7ed359100";
    const LAYOUT: &'static [(&'static str, &'static [(&'static str, &'static str)])] = &[
        (
            "sensor_msgs/Temperature",
            &[
                ("std_msgs/Header", "header"),
                ("float64", "temperature"),
                ("float64", "variance"),
            ],
        ),
        ("std_msgs/Header", HEADER_FIELDS),
    ];

    fn read_ros1(r: &mut Ros1Reader<'_>) -> Result<Self, Ros1Error> {
        Ok(Self {
            header: read_header(r)?,
            temperature: r.f64("temperature")?,
            variance: r.f64("variance")?,
        })
    }
}

/// Checks that a connection announcing `T` carries `T` as decoded here: its MD5 sum is `T`'s,
/// or else its message definition (the connection record's `message_definition`: the type's
/// fields, then each contained type after a `MSG: name` line) declares `T`'s layout field for
/// field. `Err` says what differs.
pub fn check_definition<T: Ros1Message>(md5sum: &str, definition: &str) -> Result<(), String> {
    if md5sum == T::MD5SUM {
        return Ok(());
    }
    if definition.trim().is_empty() {
        return Err(format!(
            "md5sum {md5sum} is not {}'s ({}) and the connection has no message definition",
            T::TYPE,
            T::MD5SUM
        ));
    }
    let sections = parse_definition(T::TYPE, definition);
    for (name, fields) in T::LAYOUT {
        let Some(found) = sections.iter().find(|(n, _)| same_type(n, name)) else {
            return Err(format!("the message definition lacks `MSG: {name}`"));
        };
        let found = &found.1;
        let expected: Vec<String> = fields.iter().map(|(t, f)| format!("{t} {f}")).collect();
        let same = found.len() == fields.len()
            && found
                .iter()
                .zip(fields.iter())
                .all(|((t, f), (et, ef))| same_type(t, et) && f == ef);
        if !same {
            let found: Vec<String> = found.iter().map(|(t, f)| format!("{t} {f}")).collect();
            return Err(format!(
                "the message definition's {name} has fields [{}], expected [{}]",
                found.join(", "),
                expected.join(", ")
            ));
        }
    }
    Ok(())
}

/// `Header` is `std_msgs/Header`; a type without a package matches on its name.
fn same_type(a: &str, b: &str) -> bool {
    let norm = |t: &str| {
        if t == "Header" {
            "std_msgs/Header".to_string()
        } else {
            t.to_string()
        }
    };
    let (a, b) = (norm(a), norm(b));
    if a.contains('/') && b.contains('/') {
        return a == b;
    }
    let base = |t: &str| t.rsplit('/').next().unwrap_or(t).to_string();
    base(&a) == base(&b)
}

/// A message definition as `(type, [(field type, field name)])` sections: the first is `main`,
/// each later one starts with a `MSG: type` line. Comments, blank lines and constants
/// (`TYPE NAME=VALUE`) are left out.
fn parse_definition(main: &str, text: &str) -> Vec<(String, Vec<(String, String)>)> {
    let mut sections = vec![(main.to_string(), Vec::new())];
    for raw in text.lines() {
        let line = raw.split('#').next().unwrap_or("").trim();
        if line.is_empty() || line.starts_with("===") {
            continue;
        }
        if let Some(name) = line.strip_prefix("MSG:") {
            sections.push((name.trim().to_string(), Vec::new()));
            continue;
        }
        let mut parts = line.split_whitespace();
        let (Some(ty), Some(name)) = (parts.next(), parts.next()) else {
            continue;
        };
        if name.contains('=') || parts.next().is_some_and(|p| p.starts_with('=')) {
            continue;
        }
        if let Some(s) = sections.last_mut() {
            s.1.push((ty.to_string(), name.to_string()));
        }
    }
    sections
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A `sensor_msgs/Imu` serialized field by field as ROS 1 does.
    fn imu_bytes(frame: &str) -> Vec<u8> {
        let mut b = Vec::new();
        b.extend_from_slice(&7u32.to_le_bytes()); // seq
        b.extend_from_slice(&1_700_000_000u32.to_le_bytes());
        b.extend_from_slice(&250_000_000u32.to_le_bytes());
        b.extend_from_slice(&(frame.len() as u32).to_le_bytes());
        b.extend_from_slice(frame.as_bytes());
        let mut f = |v: f64| b.extend_from_slice(&v.to_le_bytes());
        for v in [0.0, 0.0, 0.0, 1.0] {
            f(v);
        }
        (0..9).for_each(|i| f(i as f64));
        [0.1, 0.2, 0.3].into_iter().for_each(&mut f);
        (0..9).for_each(|_| f(0.0));
        [1.0, -2.0, 9.8].into_iter().for_each(&mut f);
        (0..9).for_each(|_| f(0.0));
        b
    }

    #[test]
    fn imu_is_packed_and_every_short_message_is_an_error() {
        let b = imu_bytes("imu_link");
        let m = Imu::from_ros1(&b).unwrap();
        assert_eq!(m.header.stamp.to_ns(), 1_700_000_000_250_000_000);
        assert_eq!(m.header.frame_id, "imu_link");
        assert_eq!(m.orientation.w, 1.0);
        assert_eq!(m.orientation_covariance[8], 8.0);
        assert_eq!(
            [
                m.angular_velocity.x,
                m.angular_velocity.y,
                m.angular_velocity.z
            ],
            [0.1, 0.2, 0.3]
        );
        assert_eq!(m.linear_acceleration.z, 9.8);
        for n in 0..b.len() {
            assert!(Imu::from_ros1(&b[..n]).is_err(), "{n} bytes decoded");
        }
        let mut bad = b.clone();
        bad[16] = 0xFF; // inside the frame id
        assert!(matches!(
            Imu::from_ros1(&bad),
            Err(Ros1Error::BadString { .. })
        ));
    }

    #[test]
    fn definitions_are_checked_field_for_field() {
        let def = "# a comment\nHeader header\ngeometry_msgs/Quaternion orientation\n\
                   float64[9] orientation_covariance # row major\nVector3 angular_velocity\n\
                   float64[9] angular_velocity_covariance\n\
                   geometry_msgs/Vector3 linear_acceleration\n\
                   float64[9] linear_acceleration_covariance\n====\nMSG: std_msgs/Header\n\
                   uint32 seq\ntime stamp\nstring frame_id\n====\nMSG: geometry_msgs/Quaternion\n\
                   float64 x\nfloat64 y\nfloat64 z\nfloat64 w\n====\n\
                   MSG: geometry_msgs/Vector3\nuint8 KIND=1\nfloat64 x\nfloat64 y\nfloat64 z\n";
        assert_eq!(check_definition::<Imu>(Imu::MD5SUM, ""), Ok(()));
        assert_eq!(check_definition::<Imu>("*", def), Ok(()));
        let float32 = def.replace(
            "MSG: geometry_msgs/Vector3\nuint8 KIND=1\nfloat64 x",
            "MSG: geometry_msgs/Vector3\nuint8 KIND=1\nfloat32 x",
        );
        let e = check_definition::<Imu>("*", &float32).unwrap_err();
        assert!(
            e.contains("geometry_msgs/Vector3 has fields [float32 x"),
            "{e}"
        );
        let e = check_definition::<Imu>("0123", "").unwrap_err();
        assert!(e.contains("no message definition"), "{e}");
    }
}
