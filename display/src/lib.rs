//! The display: beam selection, image drivers (quadtree, Voronoi cones,
//! spherical Delaunay mesh) and tone mapping. Nothing is implemented yet; this
//! crate only reserves its place in the workspace.
