//! A shapefile inside a zip (`roads.zip` holding roads.shp, .shx, .dbf and
//! .prj, at its root or in a folder), as QGIS and GDAL's /vsizip/ read it.
//!
//! The members are inflated into memory within `Limits`: the sizes the
//! archive declares are checked first and never trusted, so a zip bomb is
//! refused before, or at the latest while, it inflates. There is no limit
//! on the inflation ratio as the KMZ reader has: a .dbf of blank-padded
//! text fields deflates a thousandfold with nothing wrong with it; the
//! bound that matters is the bytes inflated in all.

use std::io::{BufReader, Read};
use std::path::Path;

use relief_source::SourceError;

use crate::dataset::{Dataset, Part};

/// What a zipped shapefile will read at most.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Limits {
    /// Entries in the archive.
    pub max_entries: usize,
    /// Bytes inflated, the shapefile's members together.
    pub max_inflated_bytes: u64,
}

impl Default for Limits {
    fn default() -> Self {
        Self { max_entries: 10_000, max_inflated_bytes: 1 << 30 }
    }
}

/// At most this many names are listed in a message.
const LISTED: usize = 12;

fn format(message: impl Into<String>, zip: &Path) -> SourceError {
    SourceError::format(message, zip)
}

/// The shapefile inside `zip`: its only one, or the one `layer` names (by
/// its name in the archive, or by the name's stem, as GDAL names the layers
/// of a zip). Several and no `layer` is an error listing them: showing
/// one of them while the user meant another would be worse.
pub(crate) fn open(zip: &Path, layer: Option<&str>, limits: &Limits) -> Result<Dataset, SourceError> {
    let file = relief_source::regular::open_regular(zip).map_err(|source| SourceError::Io {
        what: "zipped shapefile",
        path: zip.to_path_buf(),
        source,
    })?;
    let mut archive = zip::ZipArchive::new(BufReader::new(file))
        .map_err(|e| format(format!("not a zip archive ({})", plain(&e)), zip))?;
    if archive.len() > limits.max_entries {
        return Err(format(
            format!("the zip has {} entries, more than the limit of {}", archive.len(), limits.max_entries),
            zip,
        ));
    }
    let names: Vec<String> = archive.file_names().map(str::to_owned).collect();
    let shp = choose(&names, layer, zip)?;
    // `choose` took a name ending in ".shp" in any case: four ASCII bytes.
    let stem = &shp[..shp.len() - ".shp".len()];
    let mut budget = limits.max_inflated_bytes;
    let shp_part = inflate(&mut archive, shp, &mut budget, zip, limits)?;
    let mut sidecar = |ext: &str| -> Result<Option<Part>, SourceError> {
        let wanted = format!("{stem}.{ext}").to_ascii_lowercase();
        match names.iter().find(|n| n.to_ascii_lowercase() == wanted) {
            Some(name) => inflate(&mut archive, name, &mut budget, zip, limits).map(Some),
            None => Ok(None),
        }
    };
    Ok(Dataset {
        shx: sidecar("shx")?,
        dbf: sidecar("dbf")?,
        prj: sidecar("prj")?,
        cpg: sidecar("cpg")?,
        shp: shp_part,
    })
}

/// The name of the .shp to read, among the archive's `names`.
fn choose<'a>(names: &'a [String], layer: Option<&str>, zip: &Path) -> Result<&'a str, SourceError> {
    let shps: Vec<&str> = names.iter().map(String::as_str).filter(|n| is_shp(n)).collect();
    if let Some(layer) = layer {
        let wanted = layer.to_ascii_lowercase();
        let matches: Vec<&str> = shps
            .iter()
            .copied()
            .filter(|n| {
                let lower = n.to_ascii_lowercase();
                lower == wanted || stem(&lower) == wanted || lower.strip_suffix(".shp") == Some(wanted.as_str())
            })
            .collect();
        return match matches.as_slice() {
            [one] => Ok(one),
            [] => Err(format(format!("the zip holds no shapefile '{layer}' (it holds {})", listed(&shps)), zip)),
            several => Err(format(
                format!(
                    "the zip holds {} shapefiles named '{layer}' ({}): give the layer option the full name of one",
                    several.len(),
                    listed(several)
                ),
                zip,
            )),
        };
    }
    match shps.as_slice() {
        [one] => Ok(one),
        [] => Err(format(format!("the zip holds no shapefile (.shp) among its {} entries", names.len()), zip)),
        several @ [first, ..] => Err(format(
            format!(
                "the zip holds {} shapefiles ({}): choose one with the layer option, such as layer = \"{}\"",
                several.len(),
                listed(several),
                stem(first)
            ),
            zip,
        )),
    }
}

/// True for a .shp member, not a folder and not macOS's resource-fork
/// shadow of one (`__MACOSX/roads/._roads.shp`, which Finder's zips hold).
#[expect(clippy::case_sensitive_file_extension_comparisons, reason = "the name is lower-cased first")]
fn is_shp(name: &str) -> bool {
    let lower = name.to_ascii_lowercase();
    lower.ends_with(".shp") && !lower.starts_with("__macosx/") && !file_name(&lower).starts_with("._")
}

fn file_name(name: &str) -> &str {
    name.rsplit('/').next().unwrap_or(name)
}

/// The member's name without its folder and extension: its layer name.
fn stem(name: &str) -> &str {
    let file = file_name(name);
    file.rsplit_once('.').map_or(file, |(stem, _)| stem)
}

fn listed(names: &[&str]) -> String {
    let shown = names.iter().take(LISTED).copied().collect::<Vec<_>>().join(", ");
    match names.len().saturating_sub(LISTED) {
        0 => shown,
        more => format!("{shown} and {more} more"),
    }
}

/// The member `name`, inflated within what is left of `budget`.
fn inflate<R: Read + std::io::Seek>(
    archive: &mut zip::ZipArchive<R>,
    name: &str,
    budget: &mut u64,
    zip: &Path,
    limits: &Limits,
) -> Result<Part, SourceError> {
    let bomb = || {
        format(
            format!(
                "'{name}' in the zip inflates past the limit of {} bytes for the shapefile's files: refused as a zip bomb",
                limits.max_inflated_bytes
            ),
            zip,
        )
    };
    let mut entry =
        archive.by_name(name).map_err(|e| format(format!("cannot read '{name}' in the zip ({})", plain(&e)), zip))?;
    if entry.size() > *budget {
        return Err(bomb());
    }
    // The declared size may lie: never inflate past what is left.
    let mut bytes = Vec::new();
    entry
        .by_ref()
        .take(*budget + 1)
        .read_to_end(&mut bytes)
        .map_err(|e| format(format!("cannot inflate '{name}' in the zip ({e})"), zip))?;
    if bytes.len() as u64 > *budget {
        return Err(bomb());
    }
    *budget -= bytes.len() as u64;
    Ok(Part { path: zip.join(name.trim_start_matches('/')), bytes })
}

/// The zip crate's error in words ("i/o error" alone says too little).
fn plain(error: &zip::result::ZipError) -> String {
    match error {
        zip::result::ZipError::Io(e) => e.to_string(),
        other => other.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use std::io::Write;

    use zip::write::SimpleFileOptions;

    use super::*;

    fn zip_of(path: &Path, members: &[(&str, &[u8])]) -> Result<(), Box<dyn std::error::Error>> {
        let mut writer = zip::ZipWriter::new(std::fs::File::create(path)?);
        let options = SimpleFileOptions::default().compression_method(zip::CompressionMethod::Deflated);
        for (name, bytes) in members {
            writer.start_file(*name, options)?;
            writer.write_all(bytes)?;
        }
        writer.finish()?;
        Ok(())
    }

    #[test]
    fn a_zip_bomb_is_refused_naming_the_zip() -> Result<(), Box<dyn std::error::Error>> {
        let dir = tempfile::tempdir()?;
        let zip = dir.path().join("bomb.zip");
        let zeros = vec![0u8; 4 << 20];
        zip_of(&zip, &[("bomb.shp", &zeros), ("bomb.dbf", &zeros)])?;
        let limits = Limits { max_entries: 10, max_inflated_bytes: 6 << 20 };
        let message = open(&zip, None, &limits).unwrap_err().to_string();
        assert!(message.contains("'bomb.dbf' in the zip inflates past the limit of 6291456 bytes"), "{message}");
        assert!(message.ends_with(&format!(": {}", zip.display())), "{message}");

        let limits = Limits { max_entries: 1, max_inflated_bytes: 1 << 30 };
        let message = open(&zip, None, &limits).unwrap_err().to_string();
        assert!(message.contains("the zip has 2 entries, more than the limit of 1"), "{message}");
        Ok(())
    }

    #[test]
    fn layers_are_chosen_by_stem_or_full_name() {
        let names: Vec<String> =
            ["a/roads.shp", "a/roads.dbf", "b/Rivers.SHP", "__MACOSX/a/._roads.shp", "c/roads.shp"]
                .map(str::to_owned)
                .to_vec();
        let zip = Path::new("/d/x.zip");
        assert_eq!(choose(&names, Some("rivers"), zip).ok(), Some("b/Rivers.SHP"));
        assert_eq!(choose(&names, Some("c/roads.shp"), zip).ok(), Some("c/roads.shp"));
        assert_eq!(choose(&names, Some("a/roads"), zip).ok(), Some("a/roads.shp"));
        let message = choose(&names, Some("roads"), zip).unwrap_err().to_string();
        assert!(message.contains("2 shapefiles named 'roads' (a/roads.shp, c/roads.shp)"), "{message}");
        let message = choose(&names, None, zip).unwrap_err().to_string();
        assert!(message.contains("3 shapefiles (a/roads.shp, b/Rivers.SHP, c/roads.shp)"), "{message}");
        let message = choose(&names, Some("lakes"), zip).unwrap_err().to_string();
        assert!(message.contains("no shapefile 'lakes'"), "{message}");
    }
}
