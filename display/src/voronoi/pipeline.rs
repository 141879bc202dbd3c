//! The Voronoi driver's GPU side: the geometry distance pass and the cone
//! pass, their buffers and targets.

use std::sync::Arc;

use wgpu::util::DeviceExt;

use super::cones::{Cone, FANS};
use crate::geometry::Geometry;
use crate::gpu::build::{clearing_pass, pipeline, uniform_buffer, uniform_entry, PipelineSpec};
use crate::gpu::target::{COLOR_FORMAT, DISTANCE_FORMAT};
use crate::gpu::view::PROJECT_WGSL;
use crate::gpu::{GpuContext, GpuError, Target, TargetKind, ViewUniform};

/// The cone pass's constants.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
struct ConeUniform {
    size: [f32; 4],
    params: [f32; 4],
}

/// What one frame of cones is drawn from.
#[derive(Clone, Copy, Debug)]
pub struct ConeFrame<'a> {
    /// The view (for the geometry pass).
    pub viewport: &'a crate::Viewport,
    /// Target width in pixels.
    pub width: u32,
    /// Target height in pixels.
    pub height: u32,
    /// The cones, ordered by fan size.
    pub cones: &'a [Cone],
    /// How many cones each fan size has.
    pub by_fan: [u32; 4],
    /// Relative depth tolerance of the culling.
    pub tolerance: f32,
    /// The largest cone radius (sets the depth scale).
    pub largest: f32,
}

/// Scene geometry on the GPU.
#[derive(Debug)]
struct GeometryBuffers {
    vertices: wgpu::Buffer,
    count: u32,
    origin: glam::DVec3,
}

/// Targets of one frame size.
#[derive(Debug)]
struct Frame {
    color: Target,
    distance: Target,
    cone_bind: wgpu::BindGroup,
}

/// Pipelines, buffers and targets of a Voronoi driver.
#[derive(Debug)]
pub struct ConePipeline {
    gpu: Arc<GpuContext>,
    cones: wgpu::RenderPipeline,
    cone_layout: wgpu::BindGroupLayout,
    cone_uniform: wgpu::Buffer,
    geometry_pipeline: wgpu::RenderPipeline,
    geometry_bind: wgpu::BindGroup,
    view_uniform: wgpu::Buffer,
    geometry: Option<GeometryBuffers>,
    instances: wgpu::Buffer,
    frame: Option<Frame>,
}

impl ConePipeline {
    /// Pipelines on `gpu`, with `geometry` uploaded when given.
    pub fn new(gpu: Arc<GpuContext>, geometry: Option<&Geometry>) -> ConePipeline {
        let device = &gpu.device;
        let cone_module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("voronoi cones"),
            source: wgpu::ShaderSource::Wgsl(include_str!("cones.wgsl").into()),
        });
        let geometry_source = format!("{PROJECT_WGSL}\n{}", include_str!("geometry.wgsl"));
        let geometry_module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("voronoi geometry"),
            source: wgpu::ShaderSource::Wgsl(geometry_source.into()),
        });
        let cone_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("cones"),
            entries: &[
                uniform_entry(0, wgpu::ShaderStages::VERTEX_FRAGMENT),
                wgpu::BindGroupLayoutEntry {
                    binding: 1,
                    visibility: wgpu::ShaderStages::VERTEX_FRAGMENT,
                    ty: wgpu::BindingType::Texture {
                        sample_type: wgpu::TextureSampleType::Float { filterable: false },
                        view_dimension: wgpu::TextureViewDimension::D2,
                        multisampled: false,
                    },
                    count: None,
                },
            ],
        });
        let view_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("view"),
            entries: &[uniform_entry(0, wgpu::ShaderStages::VERTEX_FRAGMENT)],
        });
        let cone_uniform = uniform_buffer(device, "cone constants", std::mem::size_of::<ConeUniform>());
        let view_uniform = uniform_buffer(device, "view", std::mem::size_of::<ViewUniform>());
        let geometry_bind = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("view"),
            layout: &view_layout,
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: view_uniform.as_entire_binding(),
            }],
        });
        let cone_attributes = wgpu::vertex_attr_array![0 => Float32x4, 1 => Float32x4];
        let cones = pipeline(
            device,
            &PipelineSpec {
                label: "cones",
                module: &cone_module,
                groups: &[Some(&cone_layout)],
                buffer: wgpu::VertexBufferLayout {
                    array_stride: std::mem::size_of::<Cone>() as u64,
                    step_mode: wgpu::VertexStepMode::Instance,
                    attributes: &cone_attributes,
                },
                depth_compare: wgpu::CompareFunction::Less,
                format: COLOR_FORMAT,
            },
        );
        let geometry_attributes = wgpu::vertex_attr_array![0 => Float32x3];
        let geometry_pipeline = pipeline(
            device,
            &PipelineSpec {
                label: "geometry distances",
                module: &geometry_module,
                groups: &[Some(&view_layout)],
                buffer: wgpu::VertexBufferLayout {
                    array_stride: 12,
                    step_mode: wgpu::VertexStepMode::Vertex,
                    attributes: &geometry_attributes,
                },
                depth_compare: wgpu::CompareFunction::Greater,
                format: DISTANCE_FORMAT,
            },
        );
        let geometry = geometry.filter(|g| !g.triangles.is_empty()).map(|g| {
            let flat: Vec<[f32; 3]> = g.triangles.iter().flatten().map(|p| p.to_array()).collect();
            GeometryBuffers {
                vertices: device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some("scene geometry"),
                    contents: bytemuck::cast_slice(&flat),
                    usage: wgpu::BufferUsages::VERTEX,
                }),
                count: flat.len() as u32,
                origin: g.origin,
            }
        });
        let instances = instance_buffer(device, 1 << 12);
        ConePipeline {
            cones,
            cone_layout,
            cone_uniform,
            geometry_pipeline,
            geometry_bind,
            view_uniform,
            geometry,
            instances,
            frame: None,
            gpu,
        }
    }

    /// A frame drawn is still on its way back from the GPU (a web page's).
    pub fn pending(&self) -> bool {
        self.frame.as_ref().is_some_and(|f| f.color.reading())
    }

    /// True when scene geometry culls the estimates.
    pub fn has_geometry(&self) -> bool {
        self.geometry.is_some()
    }

    /// Draws `frame`'s cones and reads the frame back as RGBA floats.
    pub fn draw(&mut self, frame: &ConeFrame<'_>) -> Result<Vec<f32>, GpuError> {
        let ConeFrame {
            viewport,
            width,
            height,
            cones,
            by_fan,
            tolerance,
            largest,
        } = *frame;
        let gpu = Arc::clone(&self.gpu);
        let (device, queue) = (&gpu.device, &gpu.queue);
        // A web page's frame read back later: the one on its way comes first.
        if let Some(f) = self.frame.as_ref().filter(|f| f.color.reading()) {
            return f.color.try_read(&gpu).unwrap_or(Err(GpuError::NotReady));
        }
        if self
            .frame
            .as_ref()
            .is_none_or(|f| f.color.width != width || f.color.height != height)
        {
            let color = Target::new(&gpu, width, height, TargetKind::Color);
            let distance = Target::new(&gpu, width, height, TargetKind::Distance);
            let cone_bind = device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("cones"),
                layout: &self.cone_layout,
                entries: &[
                    wgpu::BindGroupEntry {
                        binding: 0,
                        resource: self.cone_uniform.as_entire_binding(),
                    },
                    wgpu::BindGroupEntry {
                        binding: 1,
                        resource: wgpu::BindingResource::TextureView(&distance.color_view),
                    },
                ],
            });
            self.frame = Some(Frame {
                color,
                distance,
                cone_bind,
            });
        }
        let bytes = std::mem::size_of_val(cones) as u64;
        if bytes > self.instances.size() {
            self.instances = instance_buffer(device, (bytes / std::mem::size_of::<Cone>() as u64).next_power_of_two());
        }
        if !cones.is_empty() {
            queue.write_buffer(&self.instances, 0, bytemuck::cast_slice(cones));
        }
        let culling = self.geometry.is_some();
        let uniform = ConeUniform {
            size: [
                width as f32,
                height as f32,
                largest * 1.5 + 8.0,
                if culling { 1.0 } else { 0.0 },
            ],
            params: [tolerance, 0.0, 0.0, 0.0],
        };
        queue.write_buffer(&self.cone_uniform, 0, bytemuck::bytes_of(&uniform));
        let Some(frame) = self.frame.as_ref() else {
            return Err(GpuError::Readback("no frame".into()));
        };
        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("voronoi") });
        {
            // The distance pass runs without geometry too: it clears the
            // texture the cone pass binds to "no geometry here".
            if let Some(g) = &self.geometry {
                let view = ViewUniform::new(viewport, g.origin, width, height);
                queue.write_buffer(&self.view_uniform, 0, bytemuck::bytes_of(&view));
            }
            let mut pass = clearing_pass(
                &mut encoder,
                "geometry distances",
                &frame.distance.color_view,
                wgpu::Color {
                    r: -1.0,
                    g: 0.0,
                    b: 0.0,
                    a: 0.0,
                },
                &frame.distance.depth_view,
                0.0,
            );
            if let Some(g) = &self.geometry {
                pass.set_pipeline(&self.geometry_pipeline);
                pass.set_bind_group(0, &self.geometry_bind, &[]);
                pass.set_vertex_buffer(0, g.vertices.slice(..));
                pass.draw(0..g.count, 0..1);
            }
        }
        {
            let mut pass = clearing_pass(
                &mut encoder,
                "cones",
                &frame.color.color_view,
                wgpu::Color::TRANSPARENT,
                &frame.color.depth_view,
                1.0,
            );
            pass.set_pipeline(&self.cones);
            pass.set_bind_group(0, &frame.cone_bind, &[]);
            pass.set_vertex_buffer(0, self.instances.slice(..));
            let mut first = 0u32;
            for (fan, &n) in FANS.iter().zip(&by_fan) {
                if n > 0 {
                    pass.draw(0..fan * 3, first..first + n);
                }
                first += n;
            }
        }
        frame.color.copy_out(&mut encoder);
        queue.submit([encoder.finish()]);
        frame.color.read_when_ready(&gpu)
    }
}

fn instance_buffer(device: &wgpu::Device, cones: u64) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("cones"),
        size: cones.max(1) * std::mem::size_of::<Cone>() as u64,
        usage: wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    })
}
