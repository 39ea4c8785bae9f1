//! Type descriptions: the `.msg` text a schema carries and the field list the RIHS01 hash
//! (ROS 2 REP 2011) is computed from.
//!
//! The hash is the SHA-256 of a JSON document `{"type_description": <the type>,
//! "referenced_type_descriptions": [<every type it refers to, directly or not, sorted by
//! name>]}`, each type `{"type_name": .., "fields": [{"name": .., "type": {"type_id": ..,
//! "capacity": .., "string_capacity": .., "nested_type_name": ..}}]}`, written as Python's
//! `json.dumps` writes it (`", "` and `": "` separators), which is what `rosidl` hashes.

use sha2::{Digest, Sha256};

/// A primitive field type, with its `type_description_interfaces/msg/FieldType` id.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Primitive {
    /// `int8`
    Int8,
    /// `uint8`
    Uint8,
    /// `int16`
    Int16,
    /// `uint16`
    Uint16,
    /// `int32`
    Int32,
    /// `uint32`
    Uint32,
    /// `int64`
    Int64,
    /// `uint64`
    Uint64,
    /// `float32`
    Float32,
    /// `float64`
    Float64,
    /// `bool`
    Bool,
    /// `byte` (IDL `octet`)
    Byte,
    /// `string` (unbounded)
    String,
}

impl Primitive {
    /// The FieldType id of the scalar.
    pub const fn type_id(self) -> u8 {
        match self {
            Primitive::Int8 => 2,
            Primitive::Uint8 => 3,
            Primitive::Int16 => 4,
            Primitive::Uint16 => 5,
            Primitive::Int32 => 6,
            Primitive::Uint32 => 7,
            Primitive::Int64 => 8,
            Primitive::Uint64 => 9,
            Primitive::Float32 => 10,
            Primitive::Float64 => 11,
            Primitive::Bool => 15,
            Primitive::Byte => 16,
            Primitive::String => 17,
        }
    }
}

/// What a field holds: a primitive or another message.
#[derive(Debug, Clone, Copy)]
pub enum FieldKind {
    /// A primitive.
    Primitive(Primitive),
    /// A nested message.
    Nested(&'static MessageDescription),
}

/// One value, an unbounded sequence of them, or a fixed-size array (the shapes Penelope's
/// types use; bounded sequences and strings are not among them).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Shape {
    /// A single value.
    Single,
    /// `T[]`: an unbounded sequence.
    Sequence,
    /// `T[N]`: exactly `N` values (no length on the wire).
    Array(usize),
}

/// A field of a message.
#[derive(Debug, Clone, Copy)]
pub struct FieldDescription {
    /// The field's name.
    pub name: &'static str,
    /// Its element type.
    pub kind: FieldKind,
    /// Single value or sequence.
    pub shape: Shape,
}

impl FieldDescription {
    /// A single primitive.
    pub const fn primitive(name: &'static str, primitive: Primitive) -> Self {
        Self {
            name,
            kind: FieldKind::Primitive(primitive),
            shape: Shape::Single,
        }
    }
    /// A single nested message.
    pub const fn nested(name: &'static str, message: &'static MessageDescription) -> Self {
        Self {
            name,
            kind: FieldKind::Nested(message),
            shape: Shape::Single,
        }
    }
    /// This field as a sequence.
    pub const fn sequence(self) -> Self {
        Self {
            shape: Shape::Sequence,
            ..self
        }
    }

    /// This field as a fixed-size array of `n`.
    pub const fn array(self, n: usize) -> Self {
        Self {
            shape: Shape::Array(n),
            ..self
        }
    }

    /// The FieldType id: the element's id, + 48 for a fixed-size array, + 144 for an unbounded
    /// sequence.
    pub const fn type_id(&self) -> u8 {
        let element = match self.kind {
            FieldKind::Primitive(primitive) => primitive.type_id(),
            FieldKind::Nested(_) => 1,
        };
        match self.shape {
            Shape::Single => element,
            Shape::Array(_) => element + 48,
            Shape::Sequence => element + 144,
        }
    }
}

/// A message type: its full name, its `.msg` text and its fields.
#[derive(Debug)]
pub struct MessageDescription {
    /// `"sensor_msgs/msg/JointState"`.
    pub type_name: &'static str,
    /// The `.msg` text (fields and constants, comments left out), nested types named as the
    /// ROS 2 `.msg` files name them (`std_msgs/Header`).
    pub msg_text: &'static str,
    /// The fields in declaration (and CDR) order.
    pub fields: &'static [FieldDescription],
}

impl MessageDescription {
    /// Every message type this one refers to, directly or not, without itself, each once, in
    /// depth-first order of first appearance.
    pub fn dependencies(&'static self) -> Vec<&'static MessageDescription> {
        fn visit(
            message: &'static MessageDescription,
            root: &str,
            found: &mut Vec<&'static MessageDescription>,
        ) {
            for field in message.fields {
                if let FieldKind::Nested(nested) = field.kind
                    && nested.type_name != root
                    && !found.iter().any(|seen| seen.type_name == nested.type_name)
                {
                    found.push(nested);
                    visit(nested, root, found);
                }
            }
        }
        let mut found = Vec::new();
        visit(self, self.type_name, &mut found);
        found
    }

    /// The schema MCAP's `ros2msg` encoding wants: this type's text, then per dependency a
    /// line of 80 `=`, `MSG: pkg/msg/Type` and its text.
    pub fn schema_text(&'static self) -> String {
        let mut text = String::from(self.msg_text);
        for dependency in self.dependencies() {
            if !text.ends_with('\n') {
                text.push('\n');
            }
            text.push_str(&"=".repeat(80));
            text.push_str("\nMSG: ");
            text.push_str(dependency.type_name);
            text.push('\n');
            text.push_str(dependency.msg_text);
        }
        text
    }

    /// The JSON document REP 2011 hashes (see the module's documentation).
    pub fn hashable_json(&'static self) -> String {
        let mut referenced = self.dependencies();
        referenced.sort_by_key(|message| message.type_name);
        let mut json = String::from("{\"type_description\": ");
        self.write_json(&mut json);
        json.push_str(", \"referenced_type_descriptions\": [");
        for (index, message) in referenced.iter().enumerate() {
            if index > 0 {
                json.push_str(", ");
            }
            message.write_json(&mut json);
        }
        json.push_str("]}");
        json
    }

    fn write_json(&self, json: &mut String) {
        json.push_str("{\"type_name\": ");
        push_json_string(json, self.type_name);
        json.push_str(", \"fields\": [");
        for (index, field) in self.fields.iter().enumerate() {
            if index > 0 {
                json.push_str(", ");
            }
            json.push_str("{\"name\": ");
            push_json_string(json, field.name);
            json.push_str(", \"type\": {\"type_id\": ");
            json.push_str(&field.type_id().to_string());
            // An array's capacity is its size; the other shapes' are 0 (Penelope's types have no
            // bounded sequences or strings).
            let capacity = match field.shape {
                Shape::Array(n) => n,
                Shape::Single | Shape::Sequence => 0,
            };
            json.push_str(&format!(
                ", \"capacity\": {capacity}, \"string_capacity\": 0, \"nested_type_name\": "
            ));
            match field.kind {
                FieldKind::Nested(nested) => push_json_string(json, nested.type_name),
                FieldKind::Primitive(_) => push_json_string(json, ""),
            }
            json.push_str("}}");
        }
        json.push_str("]}");
    }

    /// The RIHS01 type hash, `RIHS01_<64 lowercase hex>`.
    pub fn type_hash(&'static self) -> String {
        let digest = Sha256::digest(self.hashable_json().as_bytes());
        let mut hash = String::from("RIHS01_");
        for byte in digest {
            hash.push_str(&format!("{byte:02x}"));
        }
        hash
    }
}

/// A JSON string as Python's `json.dumps` (ensure_ascii) writes it.
fn push_json_string(json: &mut String, value: &str) {
    json.push('"');
    for character in value.chars() {
        match character {
            '"' => json.push_str("\\\""),
            '\\' => json.push_str("\\\\"),
            ' '..='~' => json.push(character),
            other => {
                let mut units = [0u16; 2];
                for unit in other.encode_utf16(&mut units) {
                    json.push_str(&format!("\\u{unit:04x}"));
                }
            }
        }
    }
    json.push('"');
}
