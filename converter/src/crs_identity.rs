//! What a coordinate reference system is, as far as telling two apart needs: the EPSG codes
//! it names (its top-level authority in WKT 1 or 2, or a compound's parts'; the projected or
//! geographic and the vertical system of GeoTIFF keys). The same system written as WKT by one
//! input and as GeoTIFF keys by another is one system; two codes that differ are two.

use strata_format::{Crs, GeoTiffKeys};

const PROJECTED: u16 = 3072;
const GEOGRAPHIC: u16 = 2048;
const VERTICAL: u16 = 4096;
/// GeoTIFF's "user-defined": no code.
const USER_DEFINED: u16 = 32767;

/// Whether `text` is WKT at all: one bracketed node (`KEYWORD[...]` or `KEYWORD(...)`) whose
/// brackets balance outside quotes. Anything else (bytes that are not text, "hello") is no CRS.
pub fn looks_like_wkt(text: &str) -> bool {
    let t = text.trim();
    let Some(open) = t.find(['[', '(']) else {
        return false;
    };
    if open == 0
        || !t[..open]
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '_')
    {
        return false;
    }
    let mut depth = 0i32;
    let mut quoted = false;
    for (i, c) in t.char_indices() {
        match c {
            '"' => quoted = !quoted,
            '[' | '(' if !quoted => depth += 1,
            ']' | ')' if !quoted => {
                depth -= 1;
                if depth == 0 {
                    return i + c.len_utf8() == t.len();
                }
            }
            _ => {}
        }
    }
    false
}

/// The EPSG codes a WKT names, sorted; `None` where it names none.
pub fn wkt_codes(wkt: &str) -> Option<Vec<u32>> {
    // Three levels are all the codes need (a compound, its parts, their authorities): a file's
    // brackets nested thousands deep are not followed (each level is a call and a copy).
    let node = Node::parse(wkt.trim(), 3)?;
    let compound = matches!(node.keyword.as_str(), "COMPD_CS" | "COMPOUNDCRS");
    let mut codes = match node.authority() {
        Some(code) => vec![code],
        // A compound without a code of its own: its parts'. Another node's children (a datum,
        // a unit) are no system.
        None if compound => node
            .children
            .iter()
            .filter(|c| c.keyword != "AUTHORITY" && c.keyword != "ID")
            .map(Node::authority)
            .collect::<Option<Vec<_>>>()?,
        None => return None,
    };
    codes.sort_unstable();
    (!codes.is_empty()).then_some(codes)
}

/// The EPSG codes GeoTIFF keys name (the projected, else the geographic system, and the
/// vertical one), sorted; `None` where they name none.
pub fn geotiff_codes(g: &GeoTiffKeys) -> Option<Vec<u32>> {
    // A header of four, then entries of four: key, where its value is (0: in the entry),
    // count, value.
    let value = |key: u16| {
        g.keys
            .get(4..)?
            .chunks_exact(4)
            .find(|e| e[0] == key && e[1] == 0)
            .map(|e| e[3])
            .filter(|&v| v != 0 && v != USER_DEFINED)
            .map(u32::from)
    };
    let mut codes: Vec<u32> = [value(PROJECTED).or(value(GEOGRAPHIC)), value(VERTICAL)]
        .into_iter()
        .flatten()
        .collect();
    codes.sort_unstable();
    (!codes.is_empty()).then_some(codes)
}

/// The codes of each way `crs` is stated: (WKT's, GeoTIFF's).
pub fn codes(crs: &Crs) -> (Option<Vec<u32>>, Option<Vec<u32>>) {
    (
        crs.wkt.as_deref().and_then(wkt_codes),
        crs.geotiff.as_ref().and_then(geotiff_codes),
    )
}

/// The codes `crs` names, where every way it is stated names the same.
pub fn agreed_codes(crs: &Crs) -> Option<Vec<u32>> {
    match codes(crs) {
        (Some(a), Some(b)) => (a == b).then_some(a),
        (a, b) => a.or(b),
    }
}

/// A WKT node: its keyword's arguments that are nodes, and its own authority.
struct Node {
    keyword: String,
    /// Its arguments, as text, with the nodes among them parsed.
    args: Vec<String>,
    children: Vec<Node>,
}

impl Node {
    /// `text` as a node, its children parsed `levels - 1` deep.
    fn parse(text: &str, levels: u32) -> Option<Node> {
        let open = text.find(['[', '('])?;
        let keyword = text[..open].trim().to_ascii_uppercase();
        let inner = text[open + 1..].trim_end();
        let inner = inner.strip_suffix([']', ')'])?;
        let args = split_top_level(inner);
        let children = match levels {
            0 | 1 => Vec::new(),
            _ => args
                .iter()
                .filter(|a| a.contains(['[', '(']) && !a.trim_start().starts_with('"'))
                .filter_map(|a| Node::parse(a.trim(), levels - 1))
                .collect(),
        };
        Some(Node {
            keyword,
            args,
            children,
        })
    }

    /// Its EPSG code: a child `AUTHORITY["EPSG","N"]` (WKT 1) or `ID["EPSG",N]` (WKT 2).
    fn authority(&self) -> Option<u32> {
        self.children
            .iter()
            .filter(|c| c.keyword == "AUTHORITY" || c.keyword == "ID")
            .find_map(|c| {
                let unquote = |s: &String| s.trim().trim_matches('"').to_string();
                let name = c.args.first().map(unquote)?;
                let code = c.args.get(1).map(unquote)?;
                name.eq_ignore_ascii_case("EPSG")
                    .then(|| code.parse().ok())
                    .flatten()
            })
    }
}

/// `text` cut at its commas outside brackets and quotes.
fn split_top_level(text: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut depth = 0i32;
    let mut quoted = false;
    let mut start = 0;
    for (i, c) in text.char_indices() {
        match c {
            '"' => quoted = !quoted,
            '[' | '(' if !quoted => depth += 1,
            ']' | ')' if !quoted => depth -= 1,
            ',' if !quoted && depth == 0 => {
                out.push(text[start..i].to_string());
                start = i + 1;
            }
            _ => {}
        }
    }
    out.push(text[start..].to_string());
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    const UTM10_WKT1: &str = r#"PROJCS["WGS 84 / UTM zone 10N",GEOGCS["WGS 84",DATUM["WGS_1984",SPHEROID["WGS 84",6378137,298.257223563,AUTHORITY["EPSG","7030"]],AUTHORITY["EPSG","6326"]],PRIMEM["Greenwich",0],UNIT["degree",0.0174532925199433],AUTHORITY["EPSG","4326"]],PROJECTION["Transverse_Mercator"],PARAMETER["central_meridian",-123],UNIT["metre",1],AUTHORITY["EPSG","32610"]]"#;
    const UTM10_WKT2: &str = r#"PROJCRS["WGS 84 / UTM zone 10N",BASEGEOGCRS["WGS 84",DATUM["World Geodetic System 1984",ELLIPSOID["WGS 84",6378137,298.257223563]],ID["EPSG",4326]],CONVERSION["UTM zone 10N",METHOD["Transverse Mercator",ID["EPSG",9807]]],CS[Cartesian,2],ID["EPSG",32610]]"#;
    const COMPOUND: &str = r#"COMPD_CS["UTM 10 + NAVD88",PROJCS["WGS 84 / UTM zone 10N",UNIT["metre",1],AUTHORITY["EPSG","32610"]],VERT_CS["NAVD88 height",VERT_DATUM["North American Vertical Datum 1988",2005],AUTHORITY["EPSG","5703"]]]"#;

    fn keys(entries: &[[u16; 4]]) -> GeoTiffKeys {
        let mut keys = vec![1, 1, 0, entries.len() as u16];
        keys.extend(entries.iter().flatten());
        GeoTiffKeys {
            keys,
            ..Default::default()
        }
    }

    #[test]
    fn one_system_written_three_ways_names_one_code() {
        assert_eq!(wkt_codes(UTM10_WKT1), Some(vec![32610]));
        assert_eq!(wkt_codes(UTM10_WKT2), Some(vec![32610]));
        assert_eq!(
            geotiff_codes(&keys(&[[3072, 0, 1, 32610]])),
            Some(vec![32610])
        );
        assert_eq!(wkt_codes(COMPOUND), Some(vec![5703, 32610]));
        let both = keys(&[[1024, 0, 1, 1], [3072, 0, 1, 32610], [4096, 0, 1, 5703]]);
        assert_eq!(geotiff_codes(&both), Some(vec![5703, 32610]));
        // No code: user-defined keys, a WKT without authority (its datum's and unit's codes
        // are no system's).
        assert_eq!(geotiff_codes(&keys(&[[3072, 0, 1, 32767]])), None);
        assert_eq!(wkt_codes(r#"LOCAL_CS["site grid",UNIT["metre",1]]"#), None);
        let datum_only = r#"GEOGCS["x",DATUM["d",AUTHORITY["EPSG","6326"]],UNIT["degree",0.01,AUTHORITY["EPSG","9122"]]]"#;
        assert_eq!(wkt_codes(datum_only), None);
        // Brackets nested far deeper than any system: no stack overflow, no code.
        let deep = format!("{}{}", "A[".repeat(100_000), "]".repeat(100_000));
        assert!(looks_like_wkt(&deep));
        assert_eq!(wkt_codes(&deep), None);
    }

    #[test]
    fn text_that_is_not_wkt_is_told() {
        for good in [
            UTM10_WKT1,
            UTM10_WKT2,
            COMPOUND,
            " GEOGCS(\"x\",UNIT(\"d\",1)) ",
        ] {
            assert!(looks_like_wkt(good), "{good}");
        }
        for bad in [
            "hello world",
            "",
            "PROJCS[\"x\"",
            "[\"x\"]",
            "PROJCS[\"x\"] tail",
            "\u{fffd}\u{fffd}",
        ] {
            assert!(!looks_like_wkt(bad), "{bad}");
        }
    }
}
