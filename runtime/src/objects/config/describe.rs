//! A kind's key list derived from its configuration type: the one description that
//! `penelope ctl kinds`, the web page's forms and the docs show.
//!
//! Three things are read from the type, none written by hand:
//! - the keys and their order: the fields its `Deserialize` impl knows, nested tables too
//!   ([`fields_of`], the parser itself asked);
//! - the help (units, ranges, meaning): the fields' doc comments, through `schemars`'s
//!   `JsonSchema` derive;
//! - the values shown: an example configuration, a value of the type ([`KindConfig::example`]),
//!   serialised as TOML, with the default noted where the example differs from it.
//!
//! The text is TOML (every key set to its example value, a comment per key), so it parses back
//! with the kind's own parser: `every_kind_round_trips_through_its_description` checks that for
//! every registered kind.

use std::cell::RefCell;
use std::collections::{BTreeMap, BTreeSet};
use std::fmt::Write as _;

use schemars::JsonSchema;
use serde::Serialize;
use serde::de::value::Error as ProbeError;
use serde::de::{self, DeserializeOwned, Deserializer, IntoDeserializer, Visitor};
use serde_json::Value as Json;

/// A kind's configuration: parsed by its `Deserialize` impl (unknown keys refused), described by
/// its `JsonSchema` (doc comments), shown with [`example`](Self::example).
pub trait KindConfig: DeserializeOwned + Serialize + JsonSchema + Default {
    /// The configuration shown: every key set (an optional key to a typical value), so that the
    /// list shows every key the parser takes. Defaults unless the type says otherwise.
    fn example() -> Self {
        Self::default()
    }
}

/// The fields a parser knows: per path of nested tables (`""` the top, `shapes`,
/// `faults.outages`), its fields in declaration order.
pub type FieldTree = BTreeMap<String, &'static [&'static str]>;

/// The fields `T`'s `Deserialize` impl knows, the nested tables' too: the parser is run on a
/// probe that records the field names each struct asks for, offering one field per run until
/// every path is explored.
pub fn fields_of<T: DeserializeOwned>() -> FieldTree {
    let state = RefCell::new(ProbeState::default());
    // Each run explores at least one more path; a configuration has far fewer than this.
    for _ in 0..10_000 {
        if state.borrow().done.contains("") {
            break;
        }
        let _ = T::deserialize(Probe {
            path: String::new(),
            state: &state,
        });
    }
    state.into_inner().tree
}

#[derive(Default)]
struct ProbeState {
    tree: FieldTree,
    /// Paths whose every field has been offered (or that are not tables).
    done: BTreeSet<String>,
}

struct Probe<'a> {
    path: String,
    state: &'a RefCell<ProbeState>,
}

impl Probe<'_> {
    fn leaf(&self) -> ProbeError {
        self.state.borrow_mut().done.insert(self.path.clone());
        de::Error::custom("leaf")
    }
}

fn join(path: &str, field: &str) -> String {
    if path.is_empty() {
        field.to_string()
    } else {
        format!("{path}.{field}")
    }
}

impl<'de> Deserializer<'de> for Probe<'_> {
    type Error = ProbeError;

    fn deserialize_any<V: Visitor<'de>>(self, _: V) -> Result<V::Value, ProbeError> {
        Err(self.leaf())
    }

    fn deserialize_struct<V: Visitor<'de>>(
        self,
        _name: &'static str,
        fields: &'static [&'static str],
        visitor: V,
    ) -> Result<V::Value, ProbeError> {
        let next = {
            let mut s = self.state.borrow_mut();
            s.tree.insert(self.path.clone(), fields);
            fields
                .iter()
                .find(|f| !s.done.contains(&join(&self.path, f)))
        };
        let Some(field) = next else {
            return Err(self.leaf());
        };
        visitor.visit_map(OneField {
            key: Some(field),
            value: Some(Probe {
                path: join(&self.path, field),
                state: self.state,
            }),
        })
    }

    fn deserialize_option<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, ProbeError> {
        visitor.visit_some(self)
    }

    fn deserialize_newtype_struct<V: Visitor<'de>>(
        self,
        _name: &'static str,
        visitor: V,
    ) -> Result<V::Value, ProbeError> {
        visitor.visit_newtype_struct(self)
    }

    fn deserialize_seq<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, ProbeError> {
        visitor.visit_seq(OneElement(Some(self)))
    }

    serde::forward_to_deserialize_any! {
        bool i8 i16 i32 i64 i128 u8 u16 u32 u64 u128 f32 f64 char str string bytes byte_buf
        unit unit_struct tuple tuple_struct map enum identifier ignored_any
    }
}

/// A table offering one key.
struct OneField<'a> {
    key: Option<&'static str>,
    value: Option<Probe<'a>>,
}

impl<'de> de::MapAccess<'de> for OneField<'_> {
    type Error = ProbeError;

    fn next_key_seed<K: de::DeserializeSeed<'de>>(
        &mut self,
        seed: K,
    ) -> Result<Option<K::Value>, ProbeError> {
        match self.key.take() {
            Some(k) => seed.deserialize(k.into_deserializer()).map(Some),
            None => Ok(None),
        }
    }

    fn next_value_seed<V: de::DeserializeSeed<'de>>(
        &mut self,
        seed: V,
    ) -> Result<V::Value, ProbeError> {
        match self.value.take() {
            Some(p) => seed.deserialize(p),
            None => Err(de::Error::custom("no value")),
        }
    }
}

/// An array offering one element (the element's type is probed at the array's path).
struct OneElement<'a>(Option<Probe<'a>>);

impl<'de> de::SeqAccess<'de> for OneElement<'_> {
    type Error = ProbeError;

    fn next_element_seed<T: de::DeserializeSeed<'de>>(
        &mut self,
        seed: T,
    ) -> Result<Option<T::Value>, ProbeError> {
        match self.0.take() {
            Some(p) => seed.deserialize(p).map(Some),
            None => Ok(None),
        }
    }
}

// ---------------------------------------------------------------------------------------------
// The text
// ---------------------------------------------------------------------------------------------

/// The column where a key's comment starts (longer lines put it two spaces after the value).
const COMMENT_COLUMN: usize = 30;
/// Comments wrap past this width.
const WIDTH: usize = 100;

/// The schema extension naming the only kinds a key applies to, on a field of a type several
/// kinds share: `#[schemars(extend("x-only-kinds" = ["robot/urdf"]))]`. Other kinds' lists leave
/// the key out.
pub const ONLY_KINDS: &str = "x-only-kinds";

/// `T`'s key list for `kind`: TOML, every key at its example value with its help (units,
/// ranges, default) in a comment; nested tables (`[[shapes]]`, `[faults]`) after the plain
/// keys.
pub fn key_text<T: KindConfig>(kind: &str) -> String {
    let schema = serde_json::to_value(schemars::schema_for!(T)).unwrap_or(Json::Null);
    let example = toml::Table::try_from(T::example()).unwrap_or_default();
    let default = toml::Table::try_from(T::default()).unwrap_or_default();
    let tree = fields_of::<T>();
    let mut out = String::new();
    Section {
        schema: &schema,
        tree: &tree,
        kind,
    }
    .write(&mut out, "", &schema, &example, Some(&default));
    out
}

/// The top-level keys of `T` that apply to other kinds only ([`ONLY_KINDS`]): parsed, but not
/// in `kind`'s list.
pub fn other_kinds_keys<T: KindConfig>(kind: &str) -> BTreeSet<String> {
    let schema = serde_json::to_value(schemars::schema_for!(T)).unwrap_or(Json::Null);
    schema
        .get("properties")
        .and_then(Json::as_object)
        .into_iter()
        .flatten()
        .filter(|(_, p)| !applies_to(p, kind))
        .map(|(k, _)| k.clone())
        .collect()
}

/// Whether a property applies to `kind` (it names no [`ONLY_KINDS`], or names `kind`).
fn applies_to(property: &Json, kind: &str) -> bool {
    match property.get(ONLY_KINDS).and_then(Json::as_array) {
        Some(kinds) => kinds.iter().any(|k| k.as_str() == Some(kind)),
        None => true,
    }
}

struct Section<'a> {
    /// The whole schema (its `$defs`).
    schema: &'a Json,
    tree: &'a FieldTree,
    /// The kind whose list this is.
    kind: &'a str,
}

impl Section<'_> {
    fn write(
        &self,
        out: &mut String,
        path: &str,
        node: &Json,
        example: &toml::Table,
        default: Option<&toml::Table>,
    ) {
        let Some(fields) = self.tree.get(path) else {
            return;
        };
        let mut tables = Vec::new();
        for field in fields.iter() {
            let Some(value) = example.get(*field) else {
                continue;
            };
            let child = join(path, field);
            let property = self.property(node, field);
            if !applies_to(&property, self.kind) {
                continue;
            }
            let mut help = help_of(&property);
            let nested = self.tree.contains_key(&child);
            match value {
                toml::Value::Table(_) if nested => {
                    tables.push((child, property, value));
                    continue;
                }
                toml::Value::Array(items)
                    if nested && !items.is_empty() && items.iter().all(|i| i.is_table()) =>
                {
                    tables.push((child, property, value));
                    continue;
                }
                _ => {}
            }
            let shown_default = match default {
                Some(d) => d.get(*field).cloned(),
                None => property
                    .get("default")
                    .and_then(|j| toml::Value::try_from(j).ok()),
            };
            // A default that differs from the example is noted; an absent one (an optional key)
            // or an empty one (a required key) is for the help to explain.
            match shown_default {
                Some(d) if &d != value && !is_empty(&d) => {
                    let _ = write!(help, " (default {})", inline(&d));
                }
                _ => {}
            }
            line(out, &format!("{field} = {}", inline(value)), &help);
        }
        for (child, property, value) in tables {
            let help = help_of(&property);
            let child_node = self.resolve(&property);
            match value {
                toml::Value::Table(t) => {
                    line(out, &format!("[{child}]"), &help);
                    self.write(out, &child, &child_node, t, None);
                }
                toml::Value::Array(items) => {
                    for (i, item) in items.iter().enumerate() {
                        let header = format!("[[{child}]]");
                        if i == 0 {
                            line(out, &header, &help);
                            if let toml::Value::Table(t) = item {
                                self.write(out, &child, &child_node, t, None);
                            }
                        } else {
                            // Another element: its values only (the help is above).
                            let _ = writeln!(out, "{header}");
                            for (k, v) in item.as_table().into_iter().flatten() {
                                let _ = writeln!(out, "{k} = {}", inline(v));
                            }
                        }
                    }
                }
                _ => {}
            }
        }
    }

    /// The schema of `node`'s property `field`.
    fn property(&self, node: &Json, field: &str) -> Json {
        let node = self.resolve(node);
        node.get("properties")
            .and_then(|p| p.get(field))
            .cloned()
            .unwrap_or(Json::Null)
    }

    /// `node` with a `$ref` (directly, as an array's items, or as an option's one branch)
    /// followed to its definition.
    fn resolve(&self, node: &Json) -> Json {
        if node.get("properties").is_some() {
            return node.clone();
        }
        let reference = node
            .get("$ref")
            .or_else(|| node.get("items").and_then(|i| i.get("$ref")))
            .or_else(|| {
                ["anyOf", "oneOf", "allOf"]
                    .iter()
                    .filter_map(|k| node.get(*k).and_then(Json::as_array))
                    .flatten()
                    .find_map(|b| b.get("$ref"))
            })
            .and_then(Json::as_str);
        match reference.and_then(|r| r.strip_prefix("#/$defs/")) {
            Some(name) => self
                .schema
                .get("$defs")
                .and_then(|d| d.get(name))
                .cloned()
                .unwrap_or(Json::Null),
            None => node.clone(),
        }
    }
}

/// A property's help: its doc comment on one line.
fn help_of(property: &Json) -> String {
    ["title", "description"]
        .iter()
        .filter_map(|k| property.get(*k).and_then(Json::as_str))
        .flat_map(str::split_whitespace)
        .collect::<Vec<_>>()
        .join(" ")
}

/// An empty string, array or table: a default the help explains (a required key, none).
fn is_empty(value: &toml::Value) -> bool {
    match value {
        toml::Value::String(s) => s.is_empty(),
        toml::Value::Array(a) => a.is_empty(),
        toml::Value::Table(t) => t.is_empty(),
        _ => false,
    }
}

/// A value as TOML on one line (tables inline).
fn inline(value: &toml::Value) -> String {
    value.to_string()
}

/// `code  # help`, the help wrapped onto indented comment lines (read as the same key's note).
fn line(out: &mut String, code: &str, help: &str) {
    if help.is_empty() {
        let _ = writeln!(out, "{code}");
        return;
    }
    let column = COMMENT_COLUMN.max(code.chars().count() + 2);
    let mut current = format!("{code:<column$}#");
    for word in help.split_whitespace() {
        if current.chars().count() + 1 + word.chars().count() > WIDTH
            && current.trim_end().ends_with(|c: char| c != '#')
        {
            let _ = writeln!(out, "{}", current.trim_end());
            // Continued at the usual column, even after a long value.
            current = format!("{:COMMENT_COLUMN$}#", "");
        }
        current.push(' ');
        current.push_str(word);
    }
    let _ = writeln!(out, "{}", current.trim_end());
}

/// What is wrong with `T`'s description, if anything: the text does not parse with `T`'s own
/// parser; an unknown key is not refused; a key shown is not a field the parser knows, or a
/// field it knows (nested tables too) is not shown; a key has no help. Empty when the
/// description and the parser agree.
pub fn description_problems(
    kind: &str,
    text: &str,
    parses: fn(&str, &str) -> Result<(), crate::objects::error::ObjectError>,
    fields: &FieldTree,
    other_kinds_keys: &BTreeSet<String>,
) -> Vec<String> {
    let mut problems = Vec::new();
    if let Err(e) = parses(kind, text) {
        problems.push(format!("its example does not parse: {e}"));
    }
    if parses(kind, &format!("no_such_key = 1\n{text}")).is_ok() {
        problems.push("an unknown key is not refused".into());
    }
    let known: BTreeSet<String> = fields
        .iter()
        .flat_map(|(path, fs)| fs.iter().map(move |f| join(path, f)))
        .filter(|k| !other_kinds_keys.contains(k))
        .collect();
    let mut shown = BTreeSet::new();
    match text.parse::<toml::Table>() {
        Ok(table) => shown_keys(&table, "", fields, &mut shown),
        Err(e) => problems.push(format!("not TOML: {e}")),
    }
    for key in known.difference(&shown) {
        problems.push(format!("`{key}` is parsed but not described"));
    }
    for key in shown.difference(&known) {
        problems.push(format!("`{key}` is described but not parsed"));
    }
    // A repeated array-of-tables element shows its keys without their help again.
    let mut headers = BTreeSet::new();
    let mut repeated = false;
    for l in text.lines() {
        let code = l.split('#').next().unwrap_or("").trim();
        let has_help = l.contains('#') && !l.trim_start().starts_with('#');
        if code.starts_with('[') {
            repeated = !headers.insert(code.to_string());
            if repeated {
                continue;
            }
        }
        if !code.is_empty() && !has_help && !repeated {
            problems.push(format!("`{code}` has no help"));
        }
    }
    problems
}

/// The keys of `table` (at `path`), nested tables' (those the parser knows as tables) too.
fn shown_keys(table: &toml::Table, path: &str, fields: &FieldTree, out: &mut BTreeSet<String>) {
    for (k, v) in table {
        let child = join(path, k);
        if fields.contains_key(&child) {
            match v {
                toml::Value::Table(t) => shown_keys(t, &child, fields, out),
                toml::Value::Array(items) => {
                    for t in items.iter().filter_map(toml::Value::as_table) {
                        shown_keys(t, &child, fields, out);
                    }
                }
                _ => {}
            }
        }
        out.insert(child);
    }
}

/// What a kind's configuration type gives the table, its type erased.
#[derive(Clone, Copy)]
pub struct Described {
    /// The key list for a kind ([`key_text`]).
    pub keys: fn(&str) -> String,
    /// The keys that apply to other kinds only ([`other_kinds_keys`]).
    pub other_kinds_keys: fn(&str) -> BTreeSet<String>,
    /// The fields its parser knows ([`fields_of`]).
    pub fields: fn() -> FieldTree,
    /// Its parser ([`parse`](crate::objects::config::parse)), the value dropped.
    pub parses: fn(&str, &str) -> Result<(), crate::objects::error::ObjectError>,
}

/// The description of configuration type `T`.
pub const fn described<T: KindConfig>() -> Described {
    Described {
        keys: key_text::<T>,
        other_kinds_keys: other_kinds_keys::<T>,
        fields: fields_of::<T>,
        parses: parses::<T>,
    }
}

fn parses<T: KindConfig>(kind: &str, text: &str) -> Result<(), crate::objects::error::ObjectError> {
    crate::objects::config::parse::<T>(kind, text).map(drop)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::objects::config::parse;
    use crate::objects::registry::catalog::KIND_TABLE;
    use serde::Deserialize;

    #[test]
    fn every_kind_round_trips_through_its_description() {
        for e in KIND_TABLE.iter() {
            let text = (e.config.keys)(e.name());
            let fields = (e.config.fields)();
            assert!(fields.contains_key(""), "{}: no fields found", e.name());
            let hidden = (e.config.other_kinds_keys)(e.name());
            let problems = description_problems(e.name(), &text, e.config.parses, &fields, &hidden);
            assert!(problems.is_empty(), "{}: {problems:#?}\n{text}", e.name());
        }
    }

    #[test]
    fn the_creator_parses_each_kind_with_the_type_its_entry_describes() {
        // `make` dispatches on the kind to its own parser: the registered description must be
        // of the type that parser takes. Every described key is known to it (its checks may
        // still refuse the example, which sets keys that exclude each other).
        for e in KIND_TABLE.iter() {
            let text = (e.config.keys)(e.name());
            if let Err(err) = crate::objects::registry::make(e.kind, "example", &text, &[]) {
                let message = err.to_string();
                assert!(
                    !message.contains("unknown field"),
                    "{}: make does not take its described keys: {message}",
                    e.name()
                );
            }
        }
    }

    /// A configuration whose description disagrees with its parser in every way the check
    /// looks for.
    #[derive(Default, Deserialize, Serialize, JsonSchema)]
    #[serde(default)]
    struct Undescribed {
        /// Documented.
        shown: u32,
        undocumented: u32,
        /// Parsed, never shown.
        #[serde(skip_serializing)]
        hidden: u32,
    }

    impl KindConfig for Undescribed {}

    fn parses_undescribed(
        kind: &str,
        text: &str,
    ) -> Result<(), crate::objects::error::ObjectError> {
        parse::<Undescribed>(kind, text).map(drop)
    }

    #[test]
    fn a_field_without_a_description_fails_the_check() {
        let text = key_text::<Undescribed>("test/undescribed");
        assert!(text.contains("shown = 0"), "{text}");
        let problems = description_problems(
            "test/undescribed",
            &text,
            parses_undescribed,
            &fields_of::<Undescribed>(),
            &BTreeSet::new(),
        );
        for expected in [
            "an unknown key is not refused",
            "`hidden` is parsed but not described",
            "`undocumented = 0` has no help",
        ] {
            assert!(
                problems.iter().any(|p| p == expected),
                "{expected} missing from {problems:#?}"
            );
        }
        // A key shown that the parser does not know.
        let more = description_problems(
            "test/undescribed",
            &format!("{text}extra = 1 # help\n"),
            parses_undescribed,
            &fields_of::<Undescribed>(),
            &BTreeSet::new(),
        );
        assert!(
            more.iter()
                .any(|p| p == "`extra` is described but not parsed"),
            "{more:#?}"
        );
    }

    #[test]
    fn the_probe_finds_nested_tables_in_declaration_order() {
        let f = fields_of::<crate::objects::kinds::SimBoardConfig>();
        assert_eq!(f[""][0], "axes");
        assert_eq!(
            f["shapes"],
            ["kind", "point", "normal", "radius", "stiffness", "damping"]
        );
        let t = fields_of::<crate::objects::teleop::TeleopConfig>();
        assert_eq!(t["faults.outages"], ["from_s", "to_s"]);
    }
}
