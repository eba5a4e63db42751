//! Names of extra-bytes fields on export that LAS readers would take for standard fields.
//! laspy and PDAL name the standard fields in their own case and spelling (`X`, `Intensity`,
//! `GpsTime`, `red`) and look extra fields up among them: laspy refused a file whose extra
//! field was named `X` ("occurs more than once"), and PDAL takes one named `Intensity` for
//! the intensity. Such a field is written as `extra_NAME`, as reading does with clashes.
//! LAS keeps 32 bytes of an extra field's name: names alike in those are cut shorter and
//! numbered, so that no two fields of the file share one.

use crate::input::extra_name;
use crate::input::las_layout::las_fields;
use crate::las_records::{NAME_BYTES, text_prefix};
use strata_format::Attribute;

/// Standard fields of LAS 1.4 as laspy and PDAL name them, beyond Strata's own names.
const READER_NAMES: [&str; 20] = [
    "x",
    "y",
    "z",
    "red",
    "green",
    "blue",
    "infrared",
    "synthetic",
    "key_point",
    "withheld",
    "overlap",
    "class_flags",
    "scan_channel",
    "wavepacket_index",
    "wavepacket_offset",
    "wavepacket_size",
    "return_point_wave_location",
    "x_t",
    "y_t",
    "z_t",
];

/// A name as readers compare them: letters and digits, in lower case.
fn key(name: &str) -> String {
    name.chars()
        .filter(char::is_ascii_alphanumeric)
        .map(|c| c.to_ascii_lowercase())
        .collect()
}

/// Why an attribute is renamed on a LAS or COPC export, in words.
pub const TAKEN_FOR_STANDARD: &str = "LAS readers take its name for a standard field";
pub const ALIKE_IN_32_BYTES: &str =
    "LAS keeps 32 bytes of a field's name, and an earlier field's begins with the same";

/// The attributes renamed for a LAS or COPC export, each with its new name and why
/// (`attributes` keep theirs). A standard field's own name is left: it is written as that
/// field.
pub fn las_export_renames(attributes: &[Attribute]) -> Vec<(usize, String, &'static str)> {
    // The legacy formats' fields (scan_angle_rank) and the extended ones'.
    let (legacy, _, _) = las_fields(5, &[]);
    let (extended, _, _) = las_fields(10, &[]);
    let own: Vec<&str> = legacy
        .iter()
        .chain(&extended)
        .map(|a| a.name.as_str())
        .collect();
    let read_as: Vec<String> = own.iter().copied().chain(READER_NAMES).map(key).collect();
    let mut names: Vec<String> = attributes.iter().map(|a| a.name.clone()).collect();
    let mut renames = Vec::new();
    for i in 0..names.len() {
        let name = names[i].clone();
        if own.contains(&name.as_str()) || !read_as.contains(&key(&name)) {
            continue;
        }
        let new = extra_name(&name, |n| {
            names.iter().any(|t| t == n) || read_as.contains(&key(n))
        });
        names[i] = new.clone();
        renames.push((i, new, TAKEN_FOR_STANDARD));
    }
    // What the file keeps of each extra field's name, the standard fields' left out.
    let mut kept: Vec<String> = Vec::new();
    for i in 0..names.len() {
        if own.contains(&names[i].as_str()) {
            continue;
        }
        if kept.iter().any(|k| k == text_prefix(&names[i], NAME_BYTES)) {
            let numbered = (2..)
                .map(|n| {
                    let suffix = format!("_{n}");
                    let start = text_prefix(&names[i], NAME_BYTES - suffix.len());
                    format!("{start}{suffix}")
                })
                .find(|n| !kept.contains(n) && !names.contains(n) && !read_as.contains(&key(n)));
            if let Some(new) = numbered {
                renames.retain(|(j, _, _)| *j != i);
                renames.push((i, new.clone(), ALIKE_IN_32_BYTES));
                names[i] = new;
            }
        }
        kept.push(text_prefix(&names[i], NAME_BYTES).to_string());
    }
    renames.sort_by_key(|(i, _, _)| *i);
    renames
}

#[cfg(test)]
mod tests {
    use super::*;
    use strata_format::AttrType;

    #[test]
    fn names_readers_take_for_standard_fields_are_renamed() {
        let names = [
            "intensity",
            "X",
            "GpsTime",
            "extra_X",
            "Red",
            "height",
            "ScanAngleRank",
        ];
        let attrs: Vec<Attribute> = names
            .iter()
            .map(|n| Attribute::new(n, AttrType::F32, 1))
            .collect();
        let renames: Vec<(usize, String)> = las_export_renames(&attrs)
            .into_iter()
            .map(|(i, n, why)| {
                assert_eq!(why, TAKEN_FOR_STANDARD);
                (i, n)
            })
            .collect();
        assert_eq!(
            renames,
            vec![
                (1, "extra_X_2".to_string()),
                (2, "extra_GpsTime".to_string()),
                (4, "extra_Red".to_string()),
                (6, "extra_ScanAngleRank".to_string())
            ]
        );
    }

    #[test]
    fn names_alike_in_their_first_32_bytes_are_numbered() {
        let long = "reflectance_of_the_second_echo_in_dB";
        let names = [
            format!("{long}_a"),
            format!("{long}_b"),
            format!("{long}_c"),
            "classification".to_string(),
            // Renamed for the other reason.
            "X".to_string(),
        ];
        let attrs: Vec<Attribute> = names
            .iter()
            .map(|n| Attribute::new(n, AttrType::F32, 1))
            .collect();
        let renames = las_export_renames(&attrs);
        let mut out = names.to_vec();
        for (i, n, why) in &renames {
            out[*i] = n.clone();
            let alike = n.starts_with("reflectance");
            assert_eq!(*why == ALIKE_IN_32_BYTES, alike, "{n}");
        }
        assert_eq!(out[0], names[0], "the first keeps its name");
        assert_eq!(out[1], "reflectance_of_the_second_echo_2");
        assert_eq!(out[2], "reflectance_of_the_second_echo_3");
        assert_eq!(out[4], "extra_X");
        let kept: Vec<&str> = out.iter().map(|n| text_prefix(n, NAME_BYTES)).collect();
        for (i, k) in kept.iter().enumerate() {
            assert!(!kept[..i].contains(k), "{k} twice in {kept:?}");
        }
    }
}
