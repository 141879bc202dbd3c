//! The variance-guided à-trous filter ([`super::atrous`]) on the GPU: the
//! same taps, weights and cut-offs in a compute shader (`atrous.wgsl`), one
//! dispatch per pass over buffers that swap between passes, on any wgpu
//! device (a GPU, or lavapipe where there is none). The per-pixel guide
//! (depth, slope, normal, filled-in variance) is prepared on the CPU as the
//! CPU filter prepares it. Results equal the CPU filter's up to float
//! rounding (the shader's `exp` and the order of its sums).

use std::sync::{Arc, OnceLock};

use glam::Vec3;
use holodeck_protocol::Picture;
use rayon::prelude::*;
use wgpu::util::DeviceExt;

use super::atrous::{fill_variance, taps, AtrousOptions};
use super::Guide;
use crate::gpu::{GpuContext, GpuError};

/// The compiled filter on one device.
pub struct GpuAtrous {
    ctx: Arc<GpuContext>,
    pipeline: wgpu::ComputePipeline,
}

/// The shader's parameters (matches `Params` in `atrous.wgsl`).
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Params {
    width: u32,
    height: u32,
    step: u32,
    sigma_normal: i32,
    sigma_luminance: f32,
    sigma_depth: f32,
    pad: [f32; 2],
}

impl GpuAtrous {
    /// The filter compiled on `ctx`'s device.
    pub fn new(ctx: Arc<GpuContext>) -> GpuAtrous {
        let module = ctx.device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("atrous"),
            source: wgpu::ShaderSource::Wgsl(include_str!("atrous.wgsl").into()),
        });
        let pipeline = ctx.device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("atrous"),
            layout: None,
            module: &module,
            entry_point: Some("main"),
            compilation_options: Default::default(),
            cache: None,
        });
        GpuAtrous { ctx, pipeline }
    }

    /// One filter for the whole process, on the shared device, compiled on
    /// first use (a failure to find a device is remembered).
    pub fn shared() -> Result<&'static GpuAtrous, GpuError> {
        static SHARED: OnceLock<Result<GpuAtrous, GpuError>> = OnceLock::new();
        SHARED
            .get_or_init(|| GpuContext::shared().map(GpuAtrous::new))
            .as_ref()
            .map_err(Clone::clone)
    }

    /// What it runs on, in words.
    pub fn describe(&self) -> String {
        self.ctx.describe()
    }

    /// `picture` filtered, guided by `guide` (same size; a picture of
    /// another size is returned as it is). Fails where the device cannot
    /// hold the frame or reading it back fails.
    pub fn filter(&self, picture: &Picture, guide: &Guide, o: &AtrousOptions) -> Result<Picture, GpuError> {
        let (w, h) = (picture.width, picture.height);
        let n = w * h;
        if n == 0 || guide.width != w || guide.height != h || picture.pixels.len() != n {
            return Ok(picture.clone());
        }
        let bytes = (n * 16) as u64;
        let limit = self
            .ctx
            .limits
            .max_storage_buffer_binding_size
            .min(self.ctx.limits.max_buffer_size);
        if bytes > limit || w > (1 << 24) || h > (1 << 24) {
            return Err(GpuError::Readback(format!(
                "a {w} x {h} frame needs {bytes} bytes per buffer, more than the device's {limit}"
            )));
        }
        let start = web_time::Instant::now();
        let (src, normals, depths) = guide_arrays(picture, guide);
        let prepared = start.elapsed();
        let device = &self.ctx.device;
        let storage = |label: &str, contents: &[u8], extra: wgpu::BufferUsages| {
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents,
                usage: wgpu::BufferUsages::STORAGE | extra,
            })
        };
        let copy = wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST;
        let ping = [
            storage("atrous ping", bytemuck::cast_slice(&src), copy),
            storage("atrous pong", bytemuck::cast_slice(&src), copy),
        ];
        let normals = storage(
            "atrous normals",
            bytemuck::cast_slice(&normals),
            wgpu::BufferUsages::empty(),
        );
        let depths = storage(
            "atrous depths",
            bytemuck::cast_slice(&depths),
            wgpu::BufferUsages::empty(),
        );
        let readback = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("atrous readback"),
            size: bytes,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let layout = self.pipeline.get_bind_group_layout(0);
        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("atrous") });
        for pass in 0..o.passes {
            let params = Params {
                width: w as u32,
                height: h as u32,
                step: 1 << pass.min(30),
                sigma_normal: o.sigma_normal,
                sigma_luminance: o.sigma_luminance,
                sigma_depth: o.sigma_depth,
                pad: [0.0; 2],
            };
            let uniform = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("atrous params"),
                contents: bytemuck::bytes_of(&params),
                usage: wgpu::BufferUsages::UNIFORM,
            });
            let (from, to) = (&ping[(pass % 2) as usize], &ping[((pass + 1) % 2) as usize]);
            let bind = self.pass_bindings(&layout, [&uniform, from, to, &normals, &depths]);
            let mut cpass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("atrous pass"),
                timestamp_writes: None,
            });
            cpass.set_pipeline(&self.pipeline);
            cpass.set_bind_group(0, &bind, &[]);
            cpass.dispatch_workgroups((w as u32).div_ceil(8), (h as u32).div_ceil(8), 1);
        }
        encoder.copy_buffer_to_buffer(&ping[(o.passes % 2) as usize], 0, &readback, 0, bytes);
        self.ctx.queue.submit([encoder.finish()]);
        let submitted = start.elapsed();
        let pixels = self.read_back(&readback)?;
        tracing::debug!(
            "atrous on the GPU, {w} x {h}: guide {:.1} ms, buffers {:.1} ms, filter and read back {:.1} ms",
            prepared.as_secs_f64() * 1e3,
            (submitted - prepared).as_secs_f64() * 1e3,
            (start.elapsed() - submitted).as_secs_f64() * 1e3
        );
        Ok(Picture {
            width: w,
            height: h,
            pixels,
        })
    }
    /// The bindings of one pass: its parameters, the buffer it reads, the
    /// one it writes, the normals and the depths (in `atrous.wgsl`'s order).
    fn pass_bindings(&self, layout: &wgpu::BindGroupLayout, buffers: [&wgpu::Buffer; 5]) -> wgpu::BindGroup {
        let entries: Vec<wgpu::BindGroupEntry<'_>> = buffers
            .iter()
            .enumerate()
            .map(|(binding, b)| wgpu::BindGroupEntry {
                binding: binding as u32,
                resource: b.as_entire_binding(),
            })
            .collect();
        self.ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("atrous pass"),
            layout,
            entries: &entries,
        })
    }

    /// The filtered colours from the mapped read-back buffer (after the
    /// work was submitted).
    fn read_back(&self, readback: &wgpu::Buffer) -> Result<Vec<Vec3>, GpuError> {
        let slice = readback.slice(..);
        let (tx, rx) = std::sync::mpsc::channel();
        slice.map_async(wgpu::MapMode::Read, move |r| {
            let _ = tx.send(r);
        });
        self.ctx.wait()?;
        rx.recv()
            .map_err(|e| GpuError::Readback(e.to_string()))?
            .map_err(|e| GpuError::Readback(e.to_string()))?;
        let pixels = {
            let mapped = slice
                .get_mapped_range()
                .map_err(|e| GpuError::Readback(e.to_string()))?;
            let floats: &[[f32; 4]] = bytemuck::cast_slice(&mapped);
            floats.iter().map(|v| Vec3::new(v[0], v[1], v[2])).collect()
        };
        readback.unmap();
        Ok(pixels)
    }
}

/// What the shader reads of each pixel: colour and filled-in variance,
/// normal and depth kind (0 unknown, 1 finite, 2 sky), depth and slope;
/// prepared as the CPU filter prepares them.
#[allow(clippy::type_complexity)]
fn guide_arrays(picture: &Picture, guide: &Guide) -> (Vec<[f32; 4]>, Vec<[f32; 4]>, Vec<[f32; 2]>) {
    let color: Vec<Vec3> = picture
        .pixels
        .iter()
        .map(|c| if c.is_finite() { c.max(Vec3::ZERO) } else { Vec3::ZERO })
        .collect();
    let variance = fill_variance(guide, &color);
    let src: Vec<[f32; 4]> = color
        .par_iter()
        .zip(&variance)
        .map(|(c, &v)| [c.x, c.y, c.z, v])
        .collect();
    let taps = taps(guide);
    let normals: Vec<[f32; 4]> = taps
        .par_iter()
        .map(|t| {
            let kind = if t.depth.is_nan() {
                0.0
            } else if t.depth.is_finite() {
                1.0
            } else {
                2.0
            };
            [t.normal.x, t.normal.y, t.normal.z, kind]
        })
        .collect();
    let depths: Vec<[f32; 2]> = taps
        .par_iter()
        .map(|t| {
            let d = if t.depth.is_finite() { t.depth } else { 0.0 };
            [d, if t.slope.is_finite() { t.slope } else { 0.0 }]
        })
        .collect();
    (src, normals, depths)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::denoise::atrous;

    /// A picture of a lit plane and a shadowed step, with noise, and its
    /// guide: depths on two planes, a patch of sky, unknown normals in a
    /// corner, unmeasured variances.
    fn scene(w: usize, h: usize) -> (Picture, Guide) {
        let mut pixels = Vec::with_capacity(w * h);
        let mut depth = Vec::with_capacity(w * h);
        let mut normal = Vec::with_capacity(w * h);
        let mut variance = Vec::with_capacity(w * h);
        for p in 0..w * h {
            let (c, r) = (p % w, p / w);
            let hash = ((p as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 40) as f32 / (1u64 << 24) as f32;
            let lit = if c < w / 2 { 4.0 } else { 0.2 };
            pixels.push(Vec3::new(lit, lit * 0.8, lit * 0.6) * (0.4 + 1.2 * hash));
            depth.push(if r < 3 {
                f32::INFINITY
            } else if c < w / 2 {
                2.0 + 0.01 * r as f32
            } else if c > w - 3 {
                f32::NAN
            } else {
                3.0
            });
            normal.push(if c < 3 && r > h - 3 { [0.0; 3] } else { [0.0, 0.0, 1.0] });
            variance.push(if p % 5 == 0 {
                f32::NAN
            } else {
                (lit * 0.3) * (lit * 0.3)
            });
        }
        let picture = Picture {
            width: w,
            height: h,
            pixels,
        };
        let guide = Guide {
            width: w,
            height: h,
            depth,
            normal,
            variance,
            albedo: Vec::new(),
        };
        (picture, guide)
    }

    #[test]
    fn the_gpu_filter_gives_the_cpu_filters_picture() {
        let ctx = match GpuContext::shared() {
            Ok(ctx) => ctx,
            Err(e) => panic!("no GPU adapter (install mesa-vulkan-drivers): {e}"),
        };
        let gpu = GpuAtrous::new(ctx);
        for (w, h) in [(37, 23), (64, 48)] {
            let (picture, guide) = scene(w, h);
            let o = AtrousOptions::default();
            let cpu = atrous(&picture, &guide, &o);
            let on_gpu = gpu.filter(&picture, &guide, &o).unwrap();
            assert_eq!((on_gpu.width, on_gpu.height), (w, h));
            let mut worst = 0.0f32;
            for (a, b) in cpu.pixels.iter().zip(&on_gpu.pixels) {
                worst = worst.max(((*a - *b).abs() / (a.abs() + Vec3::splat(1e-3))).max_element());
            }
            assert!(worst < 1e-3, "{w} x {h}: worst relative difference {worst}");
            assert_ne!(cpu, picture, "the filter changed the picture");
        }
    }

    #[test]
    fn auto_runs_the_gpu_filter_only_on_a_hardware_gpu() {
        use crate::denoise::Denoiser;
        let auto = Denoiser::parse("auto").unwrap();
        let o = AtrousOptions::default();
        let expected = if GpuContext::hardware_present() {
            Denoiser::AtrousGpu(o)
        } else {
            Denoiser::Atrous(o)
        };
        assert_eq!(auto.resolved(), expected);
        assert_eq!(Denoiser::Atrous(o).resolved(), Denoiser::Atrous(o));
        let (picture, guide) = scene(37, 23);
        assert_eq!(
            auto.apply(&picture, &guide).unwrap(),
            expected.apply(&picture, &guide).unwrap()
        );
        // Mesa's software Vulkan (all CI has) is not a hardware GPU.
        if let Ok(ctx) = GpuContext::shared() {
            if ctx.is_software() {
                assert!(!GpuContext::hardware_present(), "{}", ctx.describe());
            }
        }
    }
}
