//! `diagnostic_msgs`: the daemon's health as a `DiagnosticArray` (the `/diagnostics` topic ROS 2
//! tools such as `rqt_robot_monitor` and the diagnostic aggregator read). Field types are written
//! package-qualified (`diagnostic_msgs/KeyValue`), which the `.msg` grammar allows, so the schema
//! text stands alone.

use super::*;

/// `diagnostic_msgs/msg/KeyValue`.
pub const KEY_VALUE_DEF: MsgDefinition = MsgDefinition {
    type_name: "diagnostic_msgs/msg/KeyValue",
    text: "\
# What to label this value when viewing.
string key
# A value to track over time.
string value
",
    uses: &[],
};

/// `diagnostic_msgs/msg/DiagnosticStatus`.
pub const DIAGNOSTIC_STATUS_DEF: MsgDefinition = MsgDefinition {
    type_name: "diagnostic_msgs/msg/DiagnosticStatus",
    text: "\
# This message holds the status of an individual component of the robot.

# Possible levels of operations.
byte OK=0
byte WARN=1  # Warning
byte ERROR=2 # Error
byte STALE=3 # Stale

# Level of operation enumerated above.
byte level
# A description of the test/component reporting.
string name
# A description of the status.
string message
# A hardware unique string.
string hardware_id
# An array of values associated with the status.
diagnostic_msgs/KeyValue[] values
",
    uses: &[&KEY_VALUE_DEF],
};

/// `diagnostic_msgs/msg/DiagnosticArray`.
pub const DIAGNOSTIC_ARRAY_DEF: MsgDefinition = MsgDefinition {
    type_name: "diagnostic_msgs/msg/DiagnosticArray",
    text: "\
# This message is used to send diagnostic information about the state of the robot.
std_msgs/Header header # for timestamp
diagnostic_msgs/DiagnosticStatus[] status # an array of components being reported on
",
    uses: &[&HEADER_DEF, &DIAGNOSTIC_STATUS_DEF],
};

/// `diagnostic_msgs/msg/KeyValue`.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct KeyValue {
    /// Label.
    pub key: String,
    /// Value, as text.
    pub value: String,
}

impl RosMessage for KeyValue {
    const DEFINITION: &'static MsgDefinition = &KEY_VALUE_DEF;
    fn write_fields(&self, w: &mut CdrWriter<'_>) {
        w.string(&self.key);
        w.string(&self.value);
    }
    fn read_fields(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        Ok(Self {
            key: r.string("key")?,
            value: r.string("value")?,
        })
    }
}

/// `DiagnosticStatus.level`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[repr(u8)]
pub enum DiagnosticLevel {
    /// Working.
    #[default]
    Ok = 0,
    /// Working with a problem.
    Warn = 1,
    /// Not working.
    Error = 2,
    /// No recent information.
    Stale = 3,
}

impl DiagnosticLevel {
    fn from_byte(b: u8) -> Self {
        match b {
            0 => Self::Ok,
            1 => Self::Warn,
            2 => Self::Error,
            // 3, and anything a newer definition may add: no usable information.
            _ => Self::Stale,
        }
    }
}

/// `diagnostic_msgs/msg/DiagnosticStatus`.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct DiagnosticStatus {
    /// Level of operation.
    pub level: DiagnosticLevel,
    /// The component reporting.
    pub name: String,
    /// A description of the status.
    pub message: String,
    /// A hardware unique string.
    pub hardware_id: String,
    /// Values associated with the status.
    pub values: Vec<KeyValue>,
}

impl RosMessage for DiagnosticStatus {
    const DEFINITION: &'static MsgDefinition = &DIAGNOSTIC_STATUS_DEF;
    fn write_fields(&self, w: &mut CdrWriter<'_>) {
        w.u8(self.level as u8);
        w.string(&self.name);
        w.string(&self.message);
        w.string(&self.hardware_id);
        w.u32(u32::try_from(self.values.len()).unwrap_or(u32::MAX));
        for kv in self.values.iter().take(u32::MAX as usize) {
            kv.write_fields(w);
        }
    }
    fn read_fields(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        let level = DiagnosticLevel::from_byte(r.u8("level")?);
        let name = r.string("name")?;
        let message = r.string("message")?;
        let hardware_id = r.string("hardware_id")?;
        let n = r.u32("values")?;
        // Each element is at least two length prefixes: a corrupt count fails on the data.
        let values = (0..n)
            .map(|_| KeyValue::read_fields(r))
            .collect::<Result<_, _>>()?;
        Ok(Self {
            level,
            name,
            message,
            hardware_id,
            values,
        })
    }
}

/// `diagnostic_msgs/msg/DiagnosticArray`.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct DiagnosticArray {
    /// Time stamp.
    pub header: Header,
    /// The components reported on.
    pub status: Vec<DiagnosticStatus>,
}

impl RosMessage for DiagnosticArray {
    const DEFINITION: &'static MsgDefinition = &DIAGNOSTIC_ARRAY_DEF;
    fn write_fields(&self, w: &mut CdrWriter<'_>) {
        self.header.write_fields(w);
        w.u32(u32::try_from(self.status.len()).unwrap_or(u32::MAX));
        for s in self.status.iter().take(u32::MAX as usize) {
            s.write_fields(w);
        }
    }
    fn read_fields(r: &mut CdrReader<'_>) -> Result<Self, CdrError> {
        let header = Header::read_fields(r)?;
        let n = r.u32("status")?;
        let status = (0..n)
            .map(|_| DiagnosticStatus::read_fields(r))
            .collect::<Result<_, _>>()?;
        Ok(Self { header, status })
    }
}
