//! The `path` filter of `/current` and `/sample`: the XPath subset dashboards send, over the
//! device model (`//Axes`, `//Linear[@name="X"]`, `//DataItem[@type="POSITION"]`,
//! `//Path//DataItem[@category="CONDITION"]`, alternatives joined with `|`). The container
//! steps `Devices`, `Components` and `DataItems` may be written or left out.

use super::error::{ErrorCode, RequestError};
use super::model::DeviceModel;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Node {
    Root,
    Comp(usize),
    Item(usize),
}

struct Step {
    descendant: bool,
    name: String,
    preds: Vec<(String, String)>,
}

fn bad(path: &str, why: &str) -> RequestError {
    RequestError::new(ErrorCode::InvalidPath, format!("path {path:?}: {why}"))
}

/// The data items `path` selects (sorted), or INVALID_PATH.
pub fn select(model: &DeviceModel, path: &str) -> Result<Vec<usize>, RequestError> {
    let mut out = Vec::new();
    for alt in path.split('|') {
        let steps = parse(alt.trim()).map_err(|why| bad(path, why))?;
        let mut set = vec![Node::Root];
        for s in &steps {
            if matches!(
                s.name.as_str(),
                "MTConnectDevices" | "Devices" | "Components" | "DataItems"
            ) && s.preds.is_empty()
            {
                continue;
            }
            set = step(model, &set, s);
        }
        for n in set {
            items_under(model, n, &mut out);
        }
    }
    out.sort_unstable();
    out.dedup();
    if out.is_empty() {
        return Err(bad(
            path,
            "selects no data item of this device (see /probe)",
        ));
    }
    Ok(out)
}

fn parse(p: &str) -> Result<Vec<Step>, &'static str> {
    if !p.starts_with('/') {
        return Err("must start with / or //");
    }
    let mut steps = Vec::new();
    let mut rest = p;
    while !rest.is_empty() {
        let descendant = rest.starts_with("//");
        rest = rest.trim_start_matches('/');
        let end = step_end(rest).unwrap_or(rest.len());
        let (tok, r) = rest.split_at(end);
        rest = r;
        let (name, preds) = match tok.find('[') {
            Some(i) => (&tok[..i], predicates(&tok[i..])?),
            None => (tok, Vec::new()),
        };
        if name.is_empty()
            || !name
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || c == '*' || c == '_')
        {
            return Err(
                "a step is not an element name (the agent reads //Name[@attr=\"value\"] steps)",
            );
        }
        steps.push(Step {
            descendant,
            name: name.into(),
            preds,
        });
    }
    Ok(steps)
}

/// End of the step at the start of `s`: the next `/` outside brackets and quotes.
fn step_end(s: &str) -> Option<usize> {
    let (mut depth, mut quote) = (0, None);
    for (i, c) in s.char_indices() {
        match (c, quote) {
            ('"' | '\'', None) => quote = Some(c),
            (c, Some(q)) if c == q => quote = None,
            ('[', None) => depth += 1,
            (']', None) => depth -= 1,
            ('/', None) if depth == 0 => return Some(i),
            _ => {}
        }
    }
    None
}

/// `[@a="v"][@b='w']` → pairs.
fn predicates(mut s: &str) -> Result<Vec<(String, String)>, &'static str> {
    let mut out = Vec::new();
    while !s.is_empty() {
        let body = s
            .strip_prefix("[@")
            .ok_or("a predicate must be [@attribute=\"value\"]")?;
        let eq = body
            .find('=')
            .ok_or("a predicate must be [@attribute=\"value\"]")?;
        let attr = body[..eq].trim();
        let v = body[eq + 1..].trim_start();
        let q = v
            .chars()
            .next()
            .filter(|c| *c == '"' || *c == '\'')
            .ok_or("the value must be quoted")?;
        let close = v[1..].find(q).ok_or("unclosed quote")? + 1;
        let value = &v[1..close];
        let after = v[close + 1..].trim_start();
        s = after
            .strip_prefix(']')
            .ok_or("a predicate must end with ]")?;
        out.push((attr.to_string(), value.to_string()));
    }
    Ok(out)
}

fn children(m: &DeviceModel, n: Node) -> Vec<Node> {
    match n {
        Node::Root => vec![Node::Comp(0)],
        Node::Comp(c) => m.components[c]
            .items
            .iter()
            .map(|&i| Node::Item(i))
            .chain(m.components[c].children.iter().map(|&k| Node::Comp(k)))
            .collect(),
        Node::Item(_) => Vec::new(),
    }
}

fn descendants(m: &DeviceModel, n: Node, out: &mut Vec<Node>) {
    for k in children(m, n) {
        out.push(k);
        descendants(m, k, out);
    }
}

fn step(m: &DeviceModel, set: &[Node], s: &Step) -> Vec<Node> {
    let mut cand = Vec::new();
    for &n in set {
        if s.descendant {
            descendants(m, n, &mut cand);
        } else {
            cand.extend(children(m, n));
        }
    }
    cand.retain(|&n| matches(m, n, s));
    cand.dedup();
    cand
}

/// An attribute of a node of the model by name.
type AttrOf<'a> = Box<dyn Fn(&str) -> Option<String> + 'a>;

fn matches(m: &DeviceModel, n: Node, s: &Step) -> bool {
    let (element, attr): (&str, AttrOf) = match n {
        Node::Root => return false,
        Node::Comp(c) => {
            let comp = &m.components[c];
            (
                comp.element,
                Box::new(move |a| match a {
                    "id" => Some(comp.id.clone()),
                    "name" => comp.name.clone(),
                    "uuid" if c == 0 => Some(m.uuid.clone()),
                    _ => None,
                }),
            )
        }
        Node::Item(i) => {
            let d = &m.items[i];
            (
                "DataItem",
                Box::new(move |a| match a {
                    "id" => Some(d.id.clone()),
                    "type" => Some(d.kind.into()),
                    "subType" => d.sub_type.map(str::to_string),
                    "category" => Some(d.category.as_str().into()),
                    "units" => d.units.map(str::to_string),
                    _ => None,
                }),
            )
        }
    };
    (s.name == "*" || s.name == element)
        && s.preds.iter().all(|(k, v)| attr(k).as_deref() == Some(v))
}

fn items_under(m: &DeviceModel, n: Node, out: &mut Vec<usize>) {
    match n {
        Node::Item(i) => out.push(i),
        _ => {
            let mut all = Vec::new();
            descendants(m, n, &mut all);
            out.extend(all.into_iter().filter_map(|k| match k {
                Node::Item(i) => Some(i),
                _ => None,
            }));
        }
    }
}
