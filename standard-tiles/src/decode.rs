//! A quantized-mesh-1.0 decoder written from the format's specification, for
//! the tests only: it shares no code with the encoder.

#[derive(Debug)]
pub(crate) struct Decoded {
    pub center: [f64; 3],
    pub min_height: f32,
    pub max_height: f32,
    pub sphere_center: [f64; 3],
    pub sphere_radius: f64,
    pub horizon: [f64; 3],
    pub u: Vec<u16>,
    pub v: Vec<u16>,
    pub h: Vec<u16>,
    pub triangles: Vec<[u32; 3]>,
    pub west: Vec<u32>,
    pub south: Vec<u32>,
    pub east: Vec<u32>,
    pub north: Vec<u32>,
    /// (extension id, bytes).
    pub extensions: Vec<(u8, Vec<u8>)>,
}

struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl Reader<'_> {
    fn take<const N: usize>(&mut self) -> [u8; N] {
        let out = self.bytes[self.at..self.at + N].try_into().unwrap();
        self.at += N;
        out
    }
    fn f64(&mut self) -> f64 {
        f64::from_le_bytes(self.take())
    }
    fn f32(&mut self) -> f32 {
        f32::from_le_bytes(self.take())
    }
    fn u32(&mut self) -> u32 {
        u32::from_le_bytes(self.take())
    }
    fn u16(&mut self) -> u16 {
        u16::from_le_bytes(self.take())
    }
    fn index(&mut self, wide: bool) -> u32 {
        if wide { self.u32() } else { u32::from(self.u16()) }
    }
}

pub(crate) fn decode(bytes: &[u8]) -> Decoded {
    let mut r = Reader { bytes, at: 0 };
    let center = [r.f64(), r.f64(), r.f64()];
    let (min_height, max_height) = (r.f32(), r.f32());
    let sphere_center = [r.f64(), r.f64(), r.f64()];
    let sphere_radius = r.f64();
    let horizon = [r.f64(), r.f64(), r.f64()];
    assert_eq!(r.at, 88);
    let count = r.u32() as usize;
    let mut arrays = [vec![], vec![], vec![]];
    for array in &mut arrays {
        let mut value = 0i32;
        for _ in 0..count {
            let zz = i32::from(r.u16());
            value += (zz >> 1) ^ -(zz & 1);
            array.push(u16::try_from(value).unwrap());
        }
    }
    let [u, v, h] = arrays;
    let wide = count > 65536;
    let align = if wide { 4 } else { 2 };
    if !r.at.is_multiple_of(align) {
        r.at += align - r.at % align;
    }
    let triangle_count = r.u32() as usize;
    let mut highest = 0u32;
    let mut flat = Vec::with_capacity(triangle_count * 3);
    for _ in 0..triangle_count * 3 {
        let code = r.index(wide);
        flat.push(highest - code);
        if code == 0 {
            highest += 1;
        }
    }
    let triangles = flat.chunks(3).map(|c| [c[0], c[1], c[2]]).collect();
    let mut edges = [vec![], vec![], vec![], vec![]];
    for edge in &mut edges {
        let n = r.u32();
        for _ in 0..n {
            edge.push(r.index(wide));
        }
    }
    let [west, south, east, north] = edges;
    let mut extensions = vec![];
    while r.at < bytes.len() {
        let id = r.take::<1>()[0];
        let length = r.u32() as usize;
        extensions.push((id, bytes[r.at..r.at + length].to_vec()));
        r.at += length;
    }
    Decoded {
        center,
        min_height,
        max_height,
        sphere_center,
        sphere_radius,
        horizon,
        u,
        v,
        h,
        triangles,
        west,
        south,
        east,
        north,
        extensions,
    }
}

/// A unit vector from two oct-encoded bytes (Cesium's `octDecode`).
pub(crate) fn oct_decode(x: u8, y: u8) -> [f64; 3] {
    let from = |v: u8| f64::from(v) / 255.0 * 2.0 - 1.0;
    let (mut x, mut y) = (from(x), from(y));
    let z = 1.0 - (x.abs() + y.abs());
    if z < 0.0 {
        let old = x;
        x = (1.0 - y.abs()) * if old >= 0.0 { 1.0 } else { -1.0 };
        y = (1.0 - old.abs()) * if y >= 0.0 { 1.0 } else { -1.0 };
    }
    let l = (x * x + y * y + z * z).sqrt();
    [x / l, y / l, z / l]
}
