//! The coordinate reference system LAS files state (LAS 1.4 R15, section 2.5: records of the
//! `LASF_Projection` user), read from the inputs and written again on export, as given.

use crate::crs_identity::{codes, looks_like_wkt};
use strata_format::{Crs, GeoTiffKeys};

const USER: &str = "LASF_Projection";
const WKT: u16 = 2112;
const GEO_KEYS: u16 = 34735;
const GEO_DOUBLES: u16 = 34736;
const GEO_ASCII: u16 = 34737;

/// The CRS of a file with these (extended) VLRs, where it states one, and what a user should
/// hear of it. A WKT record that is no WKT is no CRS. Where the WKT and the GeoTIFF keys name
/// two systems, the one the global encoding's WKT bit names (`wkt_bit`) is the file's (LAS 1.4
/// R15, 2.5); where they name the same, or it cannot be told, both are kept.
pub fn crs_of<'a>(
    vlrs: impl Iterator<Item = &'a las::Vlr> + Clone,
    wkt_bit: bool,
) -> (Option<Crs>, Vec<String>) {
    let mut notes = Vec::new();
    let Some(mut crs) = stated(vlrs) else {
        return (None, notes);
    };
    if let Some(wkt) = crs.wkt.take_if(|w| !looks_like_wkt(w)) {
        notes.push(format!(
            "its WKT record holds no WKT ({:?}...): it states no coordinate reference system",
            wkt.chars().take(24).collect::<String>()
        ));
    }
    if let (Some(wkt), Some(keys)) = codes(&crs)
        && wkt != keys
    {
        let (kept, dropped) = if wkt_bit {
            crs.geotiff = None;
            (&wkt, &keys)
        } else {
            crs.wkt = None;
            (&keys, &wkt)
        };
        notes.push(format!(
            "its WKT ({}) and its GeoTIFF keys ({}) name two systems; the global encoding's WKT \
             bit ({}) makes {} the file's, and {} is ignored",
            epsg(&wkt),
            epsg(&keys),
            u8::from(wkt_bit),
            epsg(kept),
            epsg(dropped),
        ));
    }
    let some = crs.wkt.is_some() || crs.geotiff.is_some();
    (some.then_some(crs), notes)
}

/// `EPSG:32610`, or `EPSG:32610+5703` for a compound system.
pub fn epsg(codes: &[u32]) -> String {
    let codes: Vec<String> = codes.iter().map(u32::to_string).collect();
    format!("EPSG:{}", codes.join("+"))
}

/// The CRS records of a file, as they are.
fn stated<'a>(vlrs: impl Iterator<Item = &'a las::Vlr> + Clone) -> Option<Crs> {
    let find = |id: u16| {
        vlrs.clone()
            .find(|v| v.user_id == USER && v.record_id == id)
            .map(|v| v.data.as_slice())
    };
    let text = |data: &[u8]| {
        let end = data.iter().rposition(|&b| b != 0).map_or(0, |i| i + 1);
        String::from_utf8_lossy(&data[..end]).into_owned()
    };
    let wkt = find(WKT).map(text).filter(|w| !w.trim().is_empty());
    let geotiff = find(GEO_KEYS).map(|keys| GeoTiffKeys {
        keys: keys
            .chunks_exact(2)
            .map(|c| u16::from_le_bytes([c[0], c[1]]))
            .collect(),
        doubles: find(GEO_DOUBLES)
            .unwrap_or_default()
            .chunks_exact(8)
            .map(|c| f64::from_le_bytes([c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7]]))
            .collect(),
        ascii: find(GEO_ASCII).map(text).unwrap_or_default(),
    });
    // metadata.json (JSON) holds finite numbers only: keys whose doubles are not are no
    // system a reader could use either.
    let geotiff = geotiff.filter(|g| g.doubles.iter().all(|d| d.is_finite()));
    (wkt.is_some() || geotiff.is_some()).then_some(Crs { wkt, geotiff })
}

/// The records that state `crs` in a LAS file: (user, record id, description, payload).
pub fn crs_records(crs: &Crs) -> Vec<(&'static str, u16, &'static str, Vec<u8>)> {
    let mut out = Vec::new();
    if let Some(wkt) = &crs.wkt {
        let mut data = wkt.as_bytes().to_vec();
        data.push(0);
        out.push((USER, WKT, "OGC WKT", data));
    }
    if let Some(g) = &crs.geotiff {
        let keys = g.keys.iter().flat_map(|k| k.to_le_bytes()).collect();
        out.push((USER, GEO_KEYS, "GeoKeyDirectoryTag", keys));
        if !g.doubles.is_empty() {
            let doubles = g.doubles.iter().flat_map(|d| d.to_le_bytes()).collect();
            out.push((USER, GEO_DOUBLES, "GeoDoubleParamsTag", doubles));
        }
        if !g.ascii.is_empty() {
            let mut ascii = g.ascii.as_bytes().to_vec();
            ascii.push(0);
            out.push((USER, GEO_ASCII, "GeoAsciiParamsTag", ascii));
        }
    }
    out
}

/// The WKT record alone, for COPC, which states a CRS in WKT only (its point formats are 6 to
/// 8); none where there is no WKT.
pub fn wkt_record(crs: &Crs) -> Option<(&'static str, u16, &'static str, Vec<u8>)> {
    let wkt_only = Crs {
        wkt: crs.wkt.clone(),
        geotiff: None,
    };
    crs_records(&wkt_only).into_iter().next()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn records_read_back_as_the_crs_they_state() {
        let crs = Crs {
            wkt: Some("PROJCS[\"x\"]".into()),
            geotiff: Some(GeoTiffKeys {
                keys: vec![1, 1, 0, 1, 3072, 0, 1, 2992],
                doubles: vec![0.5, 6378137.0],
                ascii: "NAD83 / Oregon|".into(),
            }),
        };
        let vlrs: Vec<las::Vlr> = crs_records(&crs)
            .into_iter()
            .map(|(user, id, description, data)| las::Vlr {
                user_id: user.into(),
                record_id: id,
                description: description.into(),
                data,
            })
            .collect();
        assert_eq!(crs_of(vlrs.iter(), true).0, Some(crs.clone()));
        assert_eq!(crs_of([].iter(), true).0, None);
        // A double JSON cannot hold drops the keys, not the dataset.
        let mut nan = vlrs.clone();
        for v in nan.iter_mut().filter(|v| v.record_id == GEO_DOUBLES) {
            v.data[..8].copy_from_slice(&f64::NAN.to_le_bytes());
        }
        let wkt_only = Crs {
            geotiff: None,
            ..crs
        };
        assert_eq!(crs_of(nan.iter(), true).0, Some(wkt_only));
    }
}
