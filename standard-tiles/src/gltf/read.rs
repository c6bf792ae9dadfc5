//! The tests' reader: a GLB parsed back with the `gltf` crate (validated,
//! save for extensions it does not implement), its JSON as text, and
//! accessors read as plain values.

use ::gltf::json::validation::Validate as _;
use serde_json::Value;

use super::Glb;

pub(crate) struct Read {
    pub(crate) document: ::gltf::Document,
    pub(crate) blob: Vec<u8>,
    pub(crate) json: Value,
}

pub(crate) fn read(bytes: &[u8]) -> Read {
    let gltf = ::gltf::Gltf::from_slice_without_validation(bytes).expect("a GLB the gltf crate reads");
    let root = gltf.document.as_json();
    let mut errors = Vec::new();
    root.validate(root, ::gltf::json::Path::new, &mut |path, error| {
        let path = path().as_str().to_owned();
        // extensionsRequired names what the gltf crate does not implement.
        if !path.starts_with("extensionsRequired") {
            errors.push(format!("{path}: {error}"));
        }
    });
    assert!(errors.is_empty(), "the gltf crate finds the document invalid: {errors:?}");
    let json_len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    let json: Value = serde_json::from_slice(&bytes[20..20 + json_len]).unwrap();
    let blob = gltf.blob.clone().expect("a BIN chunk");
    Read { document: gltf.document, blob, json }
}

impl Read {
    /// The values of accessor `index`.
    pub(crate) fn values<T: ::gltf::accessor::Item + Copy>(&self, index: &Value) -> Vec<T> {
        let index = index.as_u64().expect("an accessor index") as usize;
        let accessor = self.document.accessors().nth(index).expect("the accessor");
        ::gltf::accessor::Iter::<T>::new(accessor, |_| Some(self.blob.as_slice()))
            .expect("the accessor's data")
            .collect()
    }
}

impl Read {
    /// The relief `feature_id` of each feature id, from the property table
    /// of `EXT_structural_metadata` (its buffer view 8-byte aligned).
    pub(crate) fn feature_table(&self) -> Vec<u64> {
        let metadata = &self.json["extensions"]["EXT_structural_metadata"];
        assert_eq!(metadata["schema"]["classes"]["feature"]["properties"]["feature_id"]["componentType"], "UINT64");
        let table = &metadata["propertyTables"][0];
        assert_eq!(table["class"], "feature");
        let view = &self.json["bufferViews"][table["properties"]["feature_id"]["values"].as_u64().unwrap() as usize];
        let offset = view["byteOffset"].as_u64().unwrap() as usize;
        let length = view["byteLength"].as_u64().unwrap() as usize;
        assert_eq!(offset % 8, 0);
        assert_eq!(length, 8 * table["count"].as_u64().unwrap() as usize);
        self.blob[offset..offset + length].chunks_exact(8).map(|b| u64::from_le_bytes(b.try_into().unwrap())).collect()
    }
}

/// Back from a stored position to ECEF: undo y-up ((x, y, z) stored is
/// (x, -z, y) in ECEF), then add the transform's translation.
pub(crate) fn ecef_of(glb: &Glb, stored: [f32; 3]) -> [f64; 3] {
    let [x, y, z] = stored.map(f64::from);
    let t = &glb.transform;
    [x + t[12], -z + t[13], y + t[14]]
}

/// Distance between two points, metres.
pub(crate) fn distance(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

/// Whether a region holds a geodetic point (degrees, metres), with
/// `slack` metres of height and its angle on the ground.
pub(crate) fn region_holds(region: &[f64; 6], lon_deg: f64, lat_deg: f64, h: f64, slack_m: f64) -> bool {
    let slack = slack_m / 6.3e6;
    let (lon, lat) = (lon_deg.to_radians(), lat_deg.to_radians());
    let [west, south, east, north, low, high] = *region;
    let in_lon = if west <= east {
        lon >= west - slack && lon <= east + slack
    } else {
        lon >= west - slack || lon <= east + slack
    };
    in_lon && lat >= south - slack && lat <= north + slack && h >= low - slack_m && h <= high + slack_m
}
