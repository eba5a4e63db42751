//! Names of extra-bytes fields on export that LAS readers would take for standard fields.
//! laspy and PDAL name the standard fields in their own case and spelling (`X`, `Intensity`,
//! `GpsTime`, `red`) and look extra fields up among them: laspy refused a file whose extra
//! field was named `X` ("occurs more than once"), and PDAL takes one named `Intensity` for
//! the intensity. Such a field is written as `extra_NAME`, as reading does with clashes.

use crate::input::extra_name;
use crate::input::las_layout::las_fields;
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

/// The attributes renamed for a LAS or COPC export, each with its new name (`attributes` keep
/// theirs). A standard field's own name is left: it is written as that field.
pub fn las_export_renames(attributes: &[Attribute]) -> Vec<(usize, String)> {
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
        renames.push((i, new));
    }
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
        assert_eq!(
            las_export_renames(&attrs),
            vec![
                (1, "extra_X_2".to_string()),
                (2, "extra_GpsTime".to_string()),
                (4, "extra_Red".to_string()),
                (6, "extra_ScanAngleRank".to_string())
            ]
        );
    }
}
