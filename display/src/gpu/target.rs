//! Headless render targets: a linear HDR color texture (32-bit float RGBA,
//! so nothing is clamped or quantized before tone mapping) with a depth
//! buffer, read back into the same [`Picture`] the CPU drivers produce.

use glam::Vec3;
use holodeck_protocol::Picture;

use super::context::{GpuContext, GpuError};

/// The color format every driver draws into: linear radiance, unclamped.
pub const COLOR_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba32Float;
/// The depth buffer's format.
pub const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;
/// The format of a linear-depth target (distances from the eye, as
/// [`holodeck_protocol::View::project`] measures them).
pub const DISTANCE_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::R32Float;

/// What a target's color texture holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TargetKind {
    /// Linear RGBA radiance ([`COLOR_FORMAT`]).
    Color,
    /// One float per pixel: distance from the eye ([`DISTANCE_FORMAT`]),
    /// also sampled by later passes.
    Distance,
}

/// A frame's textures on the GPU and the buffer it is read back through.
#[derive(Debug)]
pub struct Target {
    /// Frame width in pixels.
    pub width: u32,
    /// Frame height in pixels.
    pub height: u32,
    kind: TargetKind,
    color: wgpu::Texture,
    /// The color texture's view, to draw into or sample.
    pub color_view: wgpu::TextureView,
    /// The depth buffer's view.
    pub depth_view: wgpu::TextureView,
    readback: wgpu::Buffer,
    /// Bytes per row in the readback buffer (padded to wgpu's 256).
    padded_row: u32,
    /// Where a read begun without waiting ([`Target::begin_read`]) is.
    reading: std::sync::Arc<std::sync::Mutex<ReadState>>,
}

/// Where a read of the readback buffer begun without waiting is.
#[derive(Debug, Default)]
enum ReadState {
    /// None begun.
    #[default]
    Idle,
    /// The buffer is being mapped.
    Waiting,
    /// Mapped: the floats can be taken.
    Mapped,
    /// The map failed.
    Failed(String),
}

impl Target {
    /// A `width` x `height` target.
    pub fn new(ctx: &GpuContext, width: u32, height: u32, kind: TargetKind) -> Target {
        let size = wgpu::Extent3d {
            width: width.max(1),
            height: height.max(1),
            depth_or_array_layers: 1,
        };
        let format = match kind {
            TargetKind::Color => COLOR_FORMAT,
            TargetKind::Distance => DISTANCE_FORMAT,
        };
        let color = ctx.device.create_texture(&wgpu::TextureDescriptor {
            label: Some("frame color"),
            size,
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT
                | wgpu::TextureUsages::COPY_SRC
                | wgpu::TextureUsages::TEXTURE_BINDING,
            view_formats: &[],
        });
        let depth = ctx.device.create_texture(&wgpu::TextureDescriptor {
            label: Some("frame depth"),
            size,
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: DEPTH_FORMAT,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT,
            view_formats: &[],
        });
        let texel = format.block_copy_size(None).unwrap_or(16);
        let padded_row =
            (size.width * texel).div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT) * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT;
        let readback = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("frame readback"),
            size: u64::from(padded_row) * u64::from(size.height),
            usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
            mapped_at_creation: false,
        });
        Target {
            width: size.width,
            height: size.height,
            kind,
            color_view: color.create_view(&wgpu::TextureViewDescriptor::default()),
            depth_view: depth.create_view(&wgpu::TextureViewDescriptor::default()),
            color,
            readback,
            padded_row,
            reading: Default::default(),
        }
    }

    /// What the color texture holds.
    pub fn kind(&self) -> TargetKind {
        self.kind
    }

    /// Copies the color texture into the readback buffer (recorded into
    /// `encoder`; read it with [`Target::read`] after submitting).
    pub fn copy_out(&self, encoder: &mut wgpu::CommandEncoder) {
        encoder.copy_texture_to_buffer(
            wgpu::TexelCopyTextureInfo {
                texture: &self.color,
                mip_level: 0,
                origin: wgpu::Origin3d::ZERO,
                aspect: wgpu::TextureAspect::All,
            },
            wgpu::TexelCopyBufferInfo {
                buffer: &self.readback,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(self.padded_row),
                    rows_per_image: Some(self.height),
                },
            },
            wgpu::Extent3d {
                width: self.width,
                height: self.height,
                depth_or_array_layers: 1,
            },
        );
    }

    /// Maps the readback buffer (after [`Target::copy_out`] was submitted)
    /// and returns its floats row by row, top row first: 4 per pixel for a
    /// color target, 1 for a distance target.
    pub fn read(&self, ctx: &GpuContext) -> Result<Vec<f32>, GpuError> {
        let slice = self.readback.slice(..);
        let (tx, rx) = std::sync::mpsc::channel();
        slice.map_async(wgpu::MapMode::Read, move |r| {
            let _ = tx.send(r);
        });
        ctx.wait()?;
        rx.recv()
            .map_err(|e| GpuError::Readback(e.to_string()))?
            .map_err(|e| GpuError::Readback(e.to_string()))?;
        self.take_mapped()
    }

    /// Starts mapping the readback buffer (after [`Target::copy_out`] was
    /// submitted) without waiting for it, as a web page must: WebGL2
    /// finishes the GPU's work only once the page has returned to the
    /// browser. [`Target::try_read`] gives the floats once they are there.
    pub fn begin_read(&self) {
        *self.lock_reading() = ReadState::Waiting;
        let state = std::sync::Arc::clone(&self.reading);
        self.readback.slice(..).map_async(wgpu::MapMode::Read, move |r| {
            let mut s = state.lock().unwrap_or_else(|p| p.into_inner());
            *s = match r {
                Ok(()) => ReadState::Mapped,
                Err(e) => ReadState::Failed(e.to_string()),
            };
        });
    }

    /// Whether a read begun ([`Target::begin_read`]) was not taken yet:
    /// the readback buffer must not be written until it is.
    pub fn reading(&self) -> bool {
        !matches!(*self.lock_reading(), ReadState::Idle)
    }

    /// The floats of the read begun, if the GPU has finished (asked without
    /// waiting); `None` while it has not.
    pub fn try_read(&self, ctx: &GpuContext) -> Option<Result<Vec<f32>, GpuError>> {
        let _ = ctx.device.poll(wgpu::PollType::Poll);
        let state = std::mem::take(&mut *self.lock_reading());
        match state {
            ReadState::Idle => None,
            ReadState::Waiting => {
                *self.lock_reading() = ReadState::Waiting;
                None
            }
            ReadState::Failed(e) => Some(Err(GpuError::Readback(e))),
            ReadState::Mapped => Some(self.take_mapped()),
        }
    }

    fn lock_reading(&self) -> std::sync::MutexGuard<'_, ReadState> {
        self.reading.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// The mapped readback buffer's floats, row by row; unmaps it.
    fn take_mapped(&self) -> Result<Vec<f32>, GpuError> {
        let slice = self.readback.slice(..);
        let channels = match self.kind {
            TargetKind::Color => 4,
            TargetKind::Distance => 1,
        };
        let row_floats = self.width as usize * channels;
        let mut out = Vec::with_capacity(row_floats * self.height as usize);
        {
            let bytes = slice
                .get_mapped_range()
                .map_err(|e| GpuError::Readback(e.to_string()))?;
            for row in bytes.chunks_exact(self.padded_row as usize) {
                let floats: &[f32] = bytemuck::cast_slice(&row[..row_floats * 4]);
                out.extend_from_slice(floats);
            }
        }
        self.readback.unmap();
        Ok(out)
    }

    /// Reads the frame back: waiting for it natively ([`Target::read`]); in
    /// a web page, beginning the read and giving it only if the GPU already
    /// has it ([`GpuError::NotReady`] until then: call again later).
    pub fn read_when_ready(&self, ctx: &GpuContext) -> Result<Vec<f32>, GpuError> {
        if cfg!(target_arch = "wasm32") {
            self.begin_read();
            self.try_read(ctx).unwrap_or(Err(GpuError::NotReady))
        } else {
            self.read(ctx)
        }
    }
}

/// A picture of `width` x `height` pixels from RGBA floats drawn at `sub`
/// x `sub` samples per pixel: each pixel the mean of its samples that were
/// drawn (alpha above zero), black where none was, as the splat driver
/// averages the sub-pixels that hold an estimate.
pub fn downsample(rgba: &[f32], width: u32, height: u32, sub: u32) -> Picture {
    let (w, h, s) = (width as usize, height as usize, sub.max(1) as usize);
    let gw = w * s;
    let mut pixels = Vec::with_capacity(w * h);
    for row in 0..h {
        for col in 0..w {
            let (mut sum, mut n) = (Vec3::ZERO, 0u32);
            for r in row * s..(row + 1) * s {
                for c in col * s..(col + 1) * s {
                    let at = (r * gw + c) * 4;
                    if let Some(px) = rgba.get(at..at + 4) {
                        if px[3] > 0.0 {
                            sum += Vec3::new(px[0], px[1], px[2]);
                            n += 1;
                        }
                    }
                }
            }
            pixels.push(if n > 0 { sum / n as f32 } else { Vec3::ZERO });
        }
    }
    Picture {
        width: w,
        height: h,
        pixels,
    }
}

/// Gives every pixel that nothing was drawn on (alpha 0) the value of the
/// nearest pixel that was (4-connected distance, breadth-first from all
/// drawn pixels at once), as the quadtree fills its empty leaves: the
/// regions past the outermost samples (outside the mesh's hull, beyond the
/// largest cones) show the nearest sample instead of black. Filled pixels
/// get alpha 0.5. A frame with nothing drawn stays black.
pub fn fill_holes(rgba: &mut [f32], width: u32, height: u32) {
    let (w, h) = (width as usize, height as usize);
    if rgba.len() < w * h * 4 {
        return;
    }
    let mut queue: std::collections::VecDeque<usize> = (0..w * h).filter(|&i| rgba[i * 4 + 3] > 0.0).collect();
    if queue.is_empty() || queue.len() == w * h {
        return;
    }
    while let Some(i) = queue.pop_front() {
        let (x, y) = (i % w, i / w);
        let mut visit = |j: usize| {
            if rgba[j * 4 + 3] == 0.0 {
                let (src, dst) = (i * 4, j * 4);
                for c in 0..3 {
                    rgba[dst + c] = rgba[src + c];
                }
                rgba[dst + 3] = 0.5;
                queue.push_back(j);
            }
        };
        if x > 0 {
            visit(i - 1);
        }
        if x + 1 < w {
            visit(i + 1);
        }
        if y > 0 {
            visit(i - w);
        }
        if y + 1 < h {
            visit(i + w);
        }
    }
}

/// An all-black picture: what a GPU driver shows when its frame could not
/// be drawn (the error is logged).
pub fn black(width: u32, height: u32) -> Picture {
    Picture {
        width: width as usize,
        height: height as usize,
        pixels: vec![Vec3::ZERO; width as usize * height as usize],
    }
}
