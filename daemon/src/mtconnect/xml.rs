//! A thin layer over `quick-xml`'s writer for the four MTConnect documents: elements with
//! attributes, escaped text, the root element with its namespace and the common header.

use std::time::{Duration, UNIX_EPOCH};

use quick_xml::Writer;
use quick_xml::events::{BytesDecl, BytesEnd, BytesStart, BytesText, Event};

/// The standard's version this agent speaks (the schemas of `urn:mtconnect.org:*:2.5`).
pub const SCHEMA_VERSION: &str = "2.5";
/// The agent's version in the header (`version`): the schema version with a release number.
pub const AGENT_VERSION: &str = "2.5.0.0";

/// An XML document being written (into memory: the writes cannot fail).
pub struct Xml {
    w: Writer<Vec<u8>>,
}

/// Writing into a `Vec` never fails; quick-xml's `io::Result` is for other sinks.
fn mem(r: std::io::Result<()>) {
    debug_assert!(r.is_ok(), "writing XML into memory failed: {r:?}");
}

impl Xml {
    pub fn new() -> Xml {
        let mut w = Writer::new_with_indent(Vec::new(), b' ', 2);
        mem(w.write_event(Event::Decl(BytesDecl::new("1.0", Some("UTF-8"), None))));
        Xml { w }
    }

    /// Opens `name` with `attrs`.
    pub fn open(&mut self, name: &str, attrs: &[(&str, &str)]) {
        let e = BytesStart::new(name).with_attributes(attrs.iter().copied());
        mem(self.w.write_event(Event::Start(e)));
    }

    pub fn close(&mut self, name: &str) {
        mem(self.w.write_event(Event::End(BytesEnd::new(name))));
    }

    /// `<name attrs/>`.
    pub fn empty(&mut self, name: &str, attrs: &[(&str, &str)]) {
        let e = BytesStart::new(name).with_attributes(attrs.iter().copied());
        mem(self.w.write_event(Event::Empty(e)));
    }

    /// `<name attrs>text</name>` (the text escaped); an empty text gives `<name attrs/>`.
    pub fn text(&mut self, name: &str, attrs: &[(&str, &str)], text: &str) {
        if text.is_empty() {
            return self.empty(name, attrs);
        }
        let e = BytesStart::new(name).with_attributes(attrs.iter().copied());
        mem(self.w.write_event(Event::Start(e)));
        mem(self.w.write_event(Event::Text(BytesText::new(text))));
        mem(self.w.write_event(Event::End(BytesEnd::new(name))));
    }

    /// Opens the root element `MTConnect{kind}` with the 2.5 namespace and schema location.
    pub fn root(&mut self, kind: &str) {
        let ns = format!("urn:mtconnect.org:MTConnect{kind}:{SCHEMA_VERSION}");
        let loc = format!(
            "{ns} http://schemas.mtconnect.org/schemas/MTConnect{kind}_{SCHEMA_VERSION}.xsd"
        );
        self.open(
            &format!("MTConnect{kind}"),
            &[
                ("xmlns", &ns),
                ("xmlns:xsi", "http://www.w3.org/2001/XMLSchema-instance"),
                ("xsi:schemaLocation", &loc),
            ],
        );
    }

    pub fn finish(self) -> Vec<u8> {
        let mut v = self.w.into_inner();
        v.push(b'\n');
        v
    }
}

impl Default for Xml {
    fn default() -> Self {
        Xml::new()
    }
}

/// An xs:dateTime in UTC with microseconds (`2026-11-27T14:02:03.123456Z`), from ns since the
/// Unix epoch.
pub fn timestamp(ns: u64) -> String {
    humantime::format_rfc3339_micros(UNIX_EPOCH + Duration::from_nanos(ns)).to_string()
}

/// A number as an observation shows it: at most 6 decimals (µm for positions), no trailing
/// zeros, no `-0`.
pub fn number(v: f64) -> String {
    if !v.is_finite() {
        return "UNAVAILABLE".into();
    }
    let s = format!("{v:.6}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" { "0".into() } else { s.into() }
}

/// The header fields every document has.
#[derive(Clone, Debug, PartialEq)]
pub struct HeaderInfo {
    /// ns since the Unix epoch.
    pub creation_ns: u64,
    pub sender: String,
    pub instance_id: u64,
    /// When the device model was made (the agent's start), ns.
    pub model_change_ns: u64,
    pub buffer_size: usize,
    pub asset_buffer_size: usize,
    pub asset_count: usize,
}

impl HeaderInfo {
    /// The attributes common to every header, in the order agents write them.
    pub fn common(&self) -> Vec<(&'static str, String)> {
        vec![
            ("creationTime", timestamp(self.creation_ns)),
            ("sender", self.sender.clone()),
            ("instanceId", self.instance_id.to_string()),
            ("version", AGENT_VERSION.into()),
            ("deviceModelChangeTime", timestamp(self.model_change_ns)),
        ]
    }
}

/// Borrowed attribute pairs of owned values.
pub fn attrs<'a>(v: &'a [(&'a str, String)]) -> Vec<(&'a str, &'a str)> {
    v.iter().map(|(k, v)| (*k, v.as_str())).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_and_times_are_written_as_the_standard_wants() {
        assert_eq!(number(1.5), "1.5");
        assert_eq!(number(-0.0000001), "0");
        assert_eq!(number(12.0), "12");
        assert_eq!(number(f64::NAN), "UNAVAILABLE");
        assert_eq!(
            timestamp(1_500_000_000_123_456_000),
            "2017-07-14T02:40:00.123456Z"
        );
    }

    #[test]
    fn text_is_escaped() {
        let mut x = Xml::new();
        x.text("Block", &[("a", "<&\"")], "G1 X<1> & Y");
        let s = String::from_utf8(x.finish()).unwrap();
        assert!(
            s.contains("<Block a=\"&lt;&amp;&quot;\">G1 X&lt;1&gt; &amp; Y</Block>"),
            "{s}"
        );
    }
}
