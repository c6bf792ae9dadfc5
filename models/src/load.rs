//! Reading a glTF 2.0 file: the container, the JSON, its checks, and the
//! buffers the default scene's meshes use.

use std::borrow::Cow;
use std::io::Read;
use std::path::Path;

use gltf::Document;
use gltf::buffer::Source;
use gltf::json;

use relief_source::regular::open_regular;

use crate::accessor::Buffers;
use crate::{MAX_FILE_BYTES, Model, ModelError, flatten, glb, uri};

/// Extensions a file may require that change nothing this loader reads:
/// materials' looks beyond the base colour, textures, lights, and
/// quantized attributes (integer positions and normals, which the accessor
/// reader converts).
const IGNORED_EXTENSIONS: &[&str] = &[
    "KHR_lights_punctual",
    "KHR_mesh_quantization",
    "KHR_texture_basisu",
    "KHR_texture_transform",
    "EXT_texture_avif",
    "EXT_texture_webp",
];

/// Reads a `.glb` or `.gltf` file: a `.gltf` with its `.bin` buffers beside
/// it (relative paths) or inline as `data:` URIs.
pub fn load(path: &Path) -> Result<Model, ModelError> {
    let name = path.display().to_string();
    let read = |source| ModelError::Read { path: name.clone(), source };
    let bytes =
        read_limited(path).map_err(read)?.map_err(|bytes| ModelError::TooLarge { path: name.clone(), bytes })?;
    parse(&name, &bytes, path.parent())
}

/// Parses glTF bytes: a binary `.glb`, or JSON whose buffers are embedded as
/// `data:` URIs (there is no folder to find a `.bin` in). `name` stands for
/// the path in error messages.
pub fn from_slice(name: &str, bytes: &[u8]) -> Result<Model, ModelError> {
    if bytes.len() as u64 > MAX_FILE_BYTES {
        return Err(ModelError::TooLarge { path: name.to_owned(), bytes: bytes.len() as u64 });
    }
    parse(name, bytes, None)
}

/// A file's bytes, or its size when that is over [`MAX_FILE_BYTES`]. The
/// size is checked before reading and again while reading, in case the
/// file grows in between.
fn read_limited(path: &Path) -> std::io::Result<Result<Vec<u8>, u64>> {
    let file = open_regular(path)?;
    let size = file.metadata()?.len();
    if size > MAX_FILE_BYTES {
        return Ok(Err(size));
    }
    let mut bytes = Vec::with_capacity(size as usize);
    file.take(MAX_FILE_BYTES + 1).read_to_end(&mut bytes)?;
    if bytes.len() as u64 > MAX_FILE_BYTES {
        return Ok(Err(bytes.len() as u64));
    }
    Ok(Ok(bytes))
}

fn parse(name: &str, bytes: &[u8], dir: Option<&Path>) -> Result<Model, ModelError> {
    let (json_bytes, bin) =
        if glb::is_glb(bytes) { glb::split(bytes).map_err(|e| ModelError::not_gltf(name, e))? } else { (bytes, None) };
    let doc = document(name, json_bytes)?;
    let instances = flatten::instances(name, &doc)?;
    let buffers = buffers(name, &doc, &flatten::used_buffers(&instances), bin, dir)?;
    flatten::build(name, &instances, &buffers)
}

/// The validated glTF document in `json_bytes`.
fn document(name: &str, json_bytes: &[u8]) -> Result<Document, ModelError> {
    let json_bytes = json_bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(json_bytes);
    let mut root: json::Root = json::deserialize::from_slice(json_bytes)
        .map_err(|e| ModelError::not_gltf(name, why_not_gltf(json_bytes, &e)))?;
    let version = root.asset.version.as_str();
    if version.split('.').next() != Some("2") {
        return Err(ModelError::not_gltf(name, format!("it says it is glTF {version}; only glTF 2.0 is read")));
    }
    for extension in std::mem::take(&mut root.extensions_required) {
        let ignored = extension.starts_with("KHR_materials_") || IGNORED_EXTENSIONS.contains(&extension.as_str());
        if !ignored {
            return Err(ModelError::UnsupportedExtension { path: name.to_owned(), extension });
        }
    }
    repair_positions(name, &mut root)?;
    Document::from_json(root).map_err(|e| ModelError::not_gltf(name, e.to_string()))
}

/// A plain reason for JSON that does not deserialise as glTF 2.0: an old
/// glTF 1.0 file and JSON that is not glTF at all are told apart from
/// broken glTF 2.0.
fn why_not_gltf(json_bytes: &[u8], error: &json::Error) -> String {
    let Ok(value) = json::deserialize::from_slice::<json::Value>(json_bytes) else {
        return format!("it is neither JSON nor a GLB container ({error})");
    };
    match value.get("asset").and_then(|a| a.get("version")).and_then(json::Value::as_str) {
        Some(version) if !version.starts_with("2.") && version != "2" => {
            format!("it says it is glTF {version}; only glTF 2.0 is read")
        }
        Some(_) => error.to_string(),
        None => "it is JSON without a glTF 'asset' version".to_owned(),
    }
}

/// Checks what gltf's validation would index without checking (a POSITION
/// accessor that does not exist), and gives a POSITION accessor without
/// `min`/`max` placeholder ones (bounds are computed from the data, and
/// some exporters leave them out).
fn repair_positions(name: &str, root: &mut json::Root) -> Result<(), ModelError> {
    let semantic = json::validation::Checked::Valid(json::mesh::Semantic::Positions);
    let mut positions = Vec::new();
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, primitive) in mesh.primitives.iter().enumerate() {
            if let Some(index) = primitive.attributes.get(&semantic) {
                if index.value() >= root.accessors.len() {
                    return Err(ModelError::not_gltf(
                        name,
                        format!(
                            "mesh {m} primitive {p}: POSITION names accessor {}, which does not exist",
                            index.value()
                        ),
                    ));
                }
                positions.push(index.value());
            }
        }
    }
    for index in positions {
        let accessor = &mut root.accessors[index];
        for bound in [&mut accessor.min, &mut accessor.max] {
            bound.get_or_insert_with(|| json::Value::from(vec![0.0; 3]));
        }
    }
    Ok(())
}

/// The bytes of each buffer in `used`; the others are not read.
fn buffers<'a>(
    name: &str,
    doc: &Document,
    used: &[usize],
    bin: Option<&'a [u8]>,
    dir: Option<&Path>,
) -> Result<Buffers<'a>, ModelError> {
    let mut data: Vec<Option<Cow<'a, [u8]>>> = vec![None; doc.buffers().len()];
    for buffer in doc.buffers().filter(|b| used.contains(&b.index())) {
        let index = buffer.index();
        let bytes: Cow<'a, [u8]> = match buffer.source() {
            Source::Bin => Cow::Borrowed(bin.ok_or_else(|| {
                ModelError::invalid(name, format!("buffer {index} is the GLB binary chunk, but the file has none"))
            })?),
            Source::Uri(text) => Cow::Owned(uri_bytes(text, dir).map_err(|reason| ModelError::Buffer {
                path: name.to_owned(),
                index,
                uri: short(text),
                reason,
            })?),
        };
        if bytes.len() < buffer.length() {
            return Err(ModelError::invalid(
                name,
                format!("buffer {index} has {} bytes, fewer than the {} it declares", bytes.len(), buffer.length()),
            ));
        }
        data[index] = Some(bytes);
    }
    Ok(Buffers(data))
}

/// The bytes a buffer URI names: a data URI's, or a file's beside the model.
fn uri_bytes(text: &str, dir: Option<&Path>) -> Result<Vec<u8>, String> {
    if let Some(decoded) = uri::data_uri(text) {
        return decoded;
    }
    let dir = dir.ok_or("a model given as bytes has no folder to read files from")?;
    let path = uri::relative_path(dir, text)?;
    match read_limited(&path) {
        Ok(Ok(bytes)) => Ok(bytes),
        Ok(Err(size)) => {
            Err(format!("{} is {} MiB, over the {} MiB limit", path.display(), size >> 20, MAX_FILE_BYTES >> 20))
        }
        Err(e) => Err(format!("{e}: {}", path.display())),
    }
}

/// A URI short enough for a message (data URIs can be megabytes long).
fn short(uri: &str) -> String {
    match uri.char_indices().nth(48) {
        Some((end, _)) => format!("{}...", &uri[..end]),
        None => uri.to_owned(),
    }
}
