//! The companion specifications' NodeSet2 files, built into the binary, and their import
//! into the server's address space with the machine's own namespace.

use super::*;

/// The namespaces of the companion specifications the address space uses.
pub const MACHINERY_NS: &str = "http://opcfoundation.org/UA/Machinery/";
/// The Machine Tools namespace.
pub const MACHINE_TOOL_NS: &str = "http://opcfoundation.org/UA/MachineTool/";
/// The Devices (DI) namespace.
pub const DI_NS: &str = "http://opcfoundation.org/UA/DI/";

/// The companion specifications' NodeSet2 files, built into the binary, in the order they
/// depend on each other (crates/kerf/assets/opcua/README.md).
const NODESETS: [&str; 6] = [
    include_str!("../../../assets/opcua/Opc.Ua.Di.NodeSet2.xml"),
    include_str!("../../../assets/opcua/Opc.Ua.IA.NodeSet2.xml"),
    include_str!("../../../assets/opcua/Opc.Ua.Machinery.NodeSet2.xml"),
    include_str!("../../../assets/opcua/opc.ua.isa95-jobcontrol.nodeset2.xml"),
    include_str!("../../../assets/opcua/Opc.Ua.Machinery.Jobs.Nodeset2.xml"),
    include_str!("../../../assets/opcua/Opc.Ua.MachineTool.NodeSet2.xml"),
];

/// The machine's own namespace, as an import of no nodes, so that one node manager holds
/// the specifications' types and the machine's instance (references between them stay
/// within one address space).
struct OwnNamespace(String);

impl NodeSetImport for OwnNamespace {
    fn register_namespaces(&self, namespaces: &mut NodeSetNamespaceMapper) {
        namespaces.add_namespace(&self.0, 1);
    }

    fn get_own_namespaces(&self) -> Vec<String> {
        vec![self.0.clone()]
    }

    fn load<'a>(
        &'a self,
        _namespaces: &'a NodeSetNamespaceMapper,
    ) -> Box<dyn Iterator<Item = ImportedItem> + 'a> {
        Box::new(std::iter::empty())
    }
}

/// A companion specification's NodeSet2 file, imported with its namespace indexes
/// rewritten to the server's. (async-opcua 0.18's `NodeSet2Import` resolves a file's
/// indexes as if they were the server's: it registers the file's namespaces but does not
/// map its node ids through them, so a file whose `ns=1` is not the server's namespace 1
/// would land in the wrong namespace.)
struct Spec {
    /// The file's text.
    text: &'static str,
    /// The namespace URIs of the file, in its order (its index 1 first).
    uris: Vec<String>,
    /// Its indexes in the server, by its own (set when the namespaces are registered).
    map: std::sync::OnceLock<std::collections::HashMap<u16, u16>>,
    /// The file with the server's indexes (made at the import).
    import: std::sync::OnceLock<Result<NodeSet2Import, String>>,
}

impl Spec {
    fn new(text: &'static str) -> Spec {
        let uris = text
            .split_once("<NamespaceUris>")
            .and_then(|(_, rest)| rest.split_once("</NamespaceUris>"))
            .map(|(list, _)| {
                list.split("<Uri>")
                    .filter_map(|u| u.split_once("</Uri>").map(|(uri, _)| uri.trim().to_owned()))
                    .collect()
            })
            .unwrap_or_default();
        Spec {
            text,
            uris,
            map: std::sync::OnceLock::new(),
            import: std::sync::OnceLock::new(),
        }
    }
}

/// `text` with every namespace index of a node id (`ns=K;`), a browse name (`K:Name` in
/// `BrowseName="…"`) and a value's `<NamespaceIndex>K</…>` replaced by `map[K]`.
fn rewrite_indexes(text: &str, map: &std::collections::HashMap<u16, u16>) -> String {
    let mut out = String::with_capacity(text.len() + text.len() / 50);
    let mut rest = text;
    // The three forms: what precedes the index, and what follows it.
    let forms: [(&str, char); 3] = [
        ("ns=", ';'),
        ("BrowseName=\"", ':'),
        ("NamespaceIndex>", '<'),
    ];
    loop {
        let next = forms
            .iter()
            .filter_map(|(lead, end)| rest.find(lead).map(|at| (at, *lead, *end)))
            .min_by_key(|(at, _, _)| *at);
        let Some((at, lead, end)) = next else {
            out.push_str(rest);
            return out;
        };
        let after = &rest[at + lead.len()..];
        let digits = after.bytes().take_while(u8::is_ascii_digit).count();
        out.push_str(&rest[..at + lead.len()]);
        let mapped = after[..digits]
            .parse::<u16>()
            .ok()
            .filter(|_| after[digits..].starts_with(end))
            .and_then(|k| {
                if k == 0 {
                    Some(0)
                } else {
                    map.get(&k).copied()
                }
            });
        match mapped {
            Some(k) => out.push_str(&k.to_string()),
            None => out.push_str(&after[..digits]),
        }
        rest = &after[digits..];
    }
}

impl NodeSetImport for Spec {
    fn register_namespaces(&self, namespaces: &mut NodeSetNamespaceMapper) {
        for (i, uri) in self.uris.iter().enumerate() {
            namespaces.add_namespace(uri, i as u16 + 1);
        }
        let _ = self.map.set(
            namespaces
                .index_map()
                .iter()
                .map(|(k, v)| (*k, *v))
                .collect(),
        );
    }

    fn get_own_namespaces(&self) -> Vec<String> {
        self.uris.clone()
    }

    fn load<'a>(
        &'a self,
        namespaces: &'a NodeSetNamespaceMapper,
    ) -> Box<dyn Iterator<Item = ImportedItem> + 'a> {
        let import = self.import.get_or_init(|| {
            let map = self.map.get().cloned().unwrap_or_default();
            NodeSet2Import::new_str("en", &rewrite_indexes(self.text, &map), Vec::new())
                .map_err(|e| e.to_string())
        });
        match import {
            Ok(i) => i.load(namespaces),
            Err(e) => {
                eprintln!("kerf serve: a built-in NodeSet2 file could not be read: {e}");
                Box::new(std::iter::empty())
            }
        }
    }
}

/// The imports of the node manager: the specifications, then the machine's namespace.
pub(super) fn imports(ns_uri: &str) -> Vec<Box<dyn NodeSetImport>> {
    let mut all: Vec<Box<dyn NodeSetImport>> = Vec::new();
    for text in NODESETS {
        all.push(Box::new(Spec::new(text)));
    }
    all.push(Box::new(OwnNamespace(ns_uri.to_owned())));
    all
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_nodesets_indexes_are_rewritten_to_the_servers_and_nothing_else() {
        let map: std::collections::HashMap<u16, u16> = [(1, 7), (2, 3)].into_iter().collect();
        let text = r#"<UAObject NodeId="ns=1;i=13" BrowseName="1:MachineToolType" ParentNodeId="ns=2;i=5">
<Reference ReferenceType="HasSubtype" IsForward="false">ns=2;i=1001</Reference>
<Reference ReferenceType="HasComponent">i=85</Reference>
<Alias Alias="Ops">ns=0;i=9</Alias><NamespaceIndex>1</NamespaceIndex>
<Description>ns=9 BrowseName="x" 12:00</Description>"#;
        let out = rewrite_indexes(text, &map);
        assert_eq!(
            out,
            r#"<UAObject NodeId="ns=7;i=13" BrowseName="7:MachineToolType" ParentNodeId="ns=3;i=5">
<Reference ReferenceType="HasSubtype" IsForward="false">ns=3;i=1001</Reference>
<Reference ReferenceType="HasComponent">i=85</Reference>
<Alias Alias="Ops">ns=0;i=9</Alias><NamespaceIndex>7</NamespaceIndex>
<Description>ns=9 BrowseName="x" 12:00</Description>"#
        );
    }

    #[test]
    fn every_built_in_nodeset_names_its_namespaces() {
        let uris: Vec<Vec<String>> = NODESETS.iter().map(|t| Spec::new(t).uris).collect();
        assert_eq!(uris[0], ["http://opcfoundation.org/UA/DI/"]);
        assert_eq!(uris[5][0], MACHINE_TOOL_NS);
        assert!(uris[5].iter().any(|u| u == MACHINERY_NS) && uris[5].iter().any(|u| u == DI_NS));
    }
}
