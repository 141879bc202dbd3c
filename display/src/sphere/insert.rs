//! Insertion: locate, split the containing triangle into three (or the two
//! triangles of an edge into four), then Lawson flips until every edge
//! around the new vertex is Delaunay again.
//!
//! Nothing changes for a duplicate or a rejected direction. Closeness is
//! checked against the containing triangle before anything changes, and
//! against each vertex a flip is about to connect: the nearest vertex of a
//! new point always becomes its neighbour, so one that only a flip reveals
//! is still found. Such an insertion is taken back from a log of the
//! triangles it changed.

use glam::DVec3;

use super::predicates::{chord2, in_circle, side, unit};
use super::{
    corner, index_of, prefetch, tri_of, Change, Insert, SphereError, SphereMesh, Tri, VertexId, AXES, GHOSTS,
    MAX_VERTICES,
};

impl SphereMesh {
    /// [`SphereMesh::insert`], but `accept` is asked with the three vertices
    /// of the containing triangle before a vertex is added (or a ghost
    /// claimed); false gives [`Insert::Rejected`] and changes nothing.
    /// `accept` is not asked for duplicates found before the mesh changes;
    /// rarely, a vertex within `min_angle` turns up only while the mesh is
    /// updated, and the answer is [`Insert::Duplicate`] after all.
    pub fn insert_with(
        &mut self,
        dir: DVec3,
        accept: impl FnOnce([VertexId; 3]) -> bool,
    ) -> Result<Insert, SphereError> {
        let p = unit(dir)?;
        if self.dirs.len() >= MAX_VERTICES {
            return Err(SphereError::Full);
        }
        if let Some(g) = self.near_ghost(p) {
            if self.claimed[g as usize] {
                return Ok(self.duplicate(g));
            }
            let t = self.locate_counted(p).tri;
            return Ok(self.claim(g, t, accept));
        }
        let found = self.locate_counted(p);
        let t = found.tri;
        let tri = self.tris[t as usize];
        let nearest = self.nearest_of(tri.v, p);
        // On two edges' great circles means on a corner's ray; not beyond the
        // triangle's plane means not in convex position. Both are that corner,
        // and the floor on min_angle makes both rare.
        if chord2(p, self.dirs[nearest as usize]) <= self.min_chord2
            || found.zeros.count_ones() >= 2
            || !self.beyond(tri.v, p)
        {
            self.recent = nearest;
            return Ok(self.duplicate_or_claim(nearest, t, accept));
        }
        let edge = (found.zeros != 0).then(|| found.zeros.trailing_zeros() as usize);
        if let Some(i) = edge {
            let across = tri.n[i];
            let u = self.tris[tri_of(across) as usize];
            let d = u.v[index_of(across)];
            if chord2(p, self.dirs[d as usize]) <= self.min_chord2 || !self.beyond(u.v, p) {
                self.recent = d;
                return Ok(self.duplicate_or_claim(d, t, accept));
            }
        }
        if !accept(tri.v) {
            self.stats.rejected += 1;
            return Ok(Insert::Rejected);
        }

        let v = self.dirs.len() as VertexId;
        self.dirs.push(p);
        self.vert_tri.push(t);
        self.log.clear();
        self.log_base = self.tris.len() as u32;
        match edge {
            None => self.split3(t, v),
            Some(i) => self.split4(t, i, v),
        }
        match self.make_delaunay(v) {
            Ok(flips) => {
                self.stats.flips += flips;
                self.stats.insertions += 1;
                self.grid.set(p, v);
                self.recent = v;
                if self.grid.wants_growth(self.dirs.len()) {
                    self.grid.grow(&self.dirs);
                }
                Ok(Insert::Added(v))
            }
            Err(close) => {
                self.undo();
                self.stats.undone += 1;
                self.recent = close;
                Ok(self.duplicate(close))
            }
        }
    }

    /// A walk from the best known start, counted in the stats.
    fn locate_counted(&mut self, p: DVec3) -> super::locate::Located {
        let found = self.walk(p, self.walk_start(p));
        self.stats.locations += 1;
        self.stats.location_steps += found.steps;
        found
    }

    /// The ghost whose axis is within `min_angle` of unit direction `p`.
    fn near_ghost(&self, p: DVec3) -> Option<VertexId> {
        let a = p.abs();
        let k = if a.x >= a.y && a.x >= a.z {
            0
        } else if a.y >= a.z {
            1
        } else {
            2
        };
        let g = 2 * k + usize::from(p[k] < 0.0);
        (chord2(p, AXES[g]) <= self.min_chord2).then_some(g as VertexId)
    }

    /// The corner of `v` nearest to unit direction `p`.
    fn nearest_of(&self, v: [VertexId; 3], p: DVec3) -> VertexId {
        let d = v.map(|x| chord2(p, self.dirs[x as usize]));
        let mut best = 0;
        for i in 1..3 {
            if d[i] < d[best] {
                best = i;
            }
        }
        v[best]
    }

    /// Whether unit direction `p` is strictly beyond the plane of triangle
    /// `v`: inside its circumcircle, so a vertex in convex position.
    fn beyond(&self, v: [VertexId; 3], p: DVec3) -> bool {
        let [a, b, c] = v.map(|x| self.dirs[x as usize]);
        in_circle(a, b, c, p) > 0.0
    }

    fn duplicate(&mut self, v: VertexId) -> Insert {
        self.stats.duplicates += 1;
        Insert::Duplicate(v)
    }

    fn duplicate_or_claim(&mut self, v: VertexId, t: u32, accept: impl FnOnce([VertexId; 3]) -> bool) -> Insert {
        if self.is_ghost(v) {
            self.claim(v, t, accept)
        } else {
            self.duplicate(v)
        }
    }

    /// Makes ghost `g` a real vertex, if `accept` agrees for triangle `t`.
    fn claim(&mut self, g: VertexId, t: u32, accept: impl FnOnce([VertexId; 3]) -> bool) -> Insert {
        if !accept(self.tris[t as usize].v) {
            self.stats.rejected += 1;
            return Insert::Rejected;
        }
        self.claimed[g as usize] = true;
        self.stats.insertions += 1;
        self.grid.set(AXES[g as usize], g);
        self.recent = g;
        Insert::Added(g)
    }

    /// Splits triangle `t` = (a, b, c) around new vertex `p` inside it into
    /// (p, b, c) in slot `t`, (p, c, a) and (p, a, b) in new slots.
    fn split3(&mut self, t: u32, p: VertexId) {
        let old = self.tris[t as usize];
        let Tri {
            v: [a, b, c],
            n: [na, nb, nc],
            o: [oa, ob, oc],
        } = old;
        for (far, across) in [(oa, na), (ob, nb), (oc, nc)] {
            prefetch(&self.dirs[far as usize]);
            prefetch(&self.tris[tri_of(across) as usize]);
        }
        let t1 = self.tris.len() as u32;
        let t2 = t1 + 1;
        self.log.push(Change::Tri(t, old));
        self.tris[t as usize] = Tri {
            v: [p, b, c],
            n: [na, corner(t1, 2), corner(t2, 1)],
            o: [oa, a, a],
        };
        self.tris.push(Tri {
            v: [p, c, a],
            n: [nb, corner(t2, 2), corner(t, 1)],
            o: [ob, b, b],
        });
        self.tris.push(Tri {
            v: [p, a, b],
            n: [nc, corner(t, 2), corner(t1, 1)],
            o: [oc, c, c],
        });
        self.link(na, (corner(t, 0), a), (corner(t, 0), p));
        self.link(nb, (corner(t, 1), b), (corner(t1, 0), p));
        self.link(nc, (corner(t, 2), c), (corner(t2, 0), p));
        // b and c are still in t.
        self.vert_tri[p as usize] = t;
        self.vert_tri[a as usize] = t1;
        self.stack.clear();
        self.stack.extend_from_slice(&[t, t1, t2]);
    }

    /// Splits the edge opposite corner `i` of triangle `t`, on whose great
    /// circle new vertex `p` lies, and the triangle across it, into four.
    fn split4(&mut self, t: u32, i: usize, p: VertexId) {
        let (i1, i2) = ((i + 1) % 3, (i + 2) % 3);
        let old_t = self.tris[t as usize];
        // t = (c, a, b) with the split edge a→b; u = (d, b, a) across it.
        let (c, a, b) = (old_t.v[i], old_t.v[i1], old_t.v[i2]);
        let (u, j) = (tri_of(old_t.n[i]), index_of(old_t.n[i]));
        let (j1, j2) = ((j + 1) % 3, (j + 2) % 3);
        let old_u = self.tris[u as usize];
        let d = old_u.v[j];
        let (ta, tb, ua, ub) = (old_t.n[i1], old_t.n[i2], old_u.n[j1], old_u.n[j2]);
        for far in [old_t.o[i1], old_t.o[i2], old_u.o[j1], old_u.o[j2]] {
            prefetch(&self.dirs[far as usize]);
        }
        let t1 = self.tris.len() as u32;
        let t3 = t1 + 1;
        self.log.push(Change::Tri(t, old_t));
        self.log.push(Change::Tri(u, old_u));
        self.tris[t as usize] = Tri {
            v: [p, b, c],
            n: [ta, corner(t1, 2), corner(t3, 1)],
            o: [old_t.o[i1], a, d],
        };
        self.tris.push(Tri {
            v: [p, c, a],
            n: [tb, corner(u, 2), corner(t, 1)],
            o: [old_t.o[i2], d, b],
        });
        self.tris[u as usize] = Tri {
            v: [p, a, d],
            n: [ua, corner(t3, 2), corner(t1, 1)],
            o: [old_u.o[j1], b, c],
        };
        self.tris.push(Tri {
            v: [p, d, b],
            n: [ub, corner(t, 2), corner(u, 1)],
            o: [old_u.o[j2], c, a],
        });
        self.link(ta, (corner(t, i1), a), (corner(t, 0), p));
        self.link(tb, (corner(t, i2), b), (corner(t1, 0), p));
        self.link(ua, (corner(u, j1), b), (corner(u, 0), p));
        self.link(ub, (corner(u, j2), a), (corner(t3, 0), p));
        // c is still in t, d in u.
        self.vert_tri[p as usize] = t;
        self.vert_tri[a as usize] = u;
        self.vert_tri[b as usize] = t;
        self.stack.clear();
        self.stack.extend_from_slice(&[t, t1, u, t3]);
    }

    /// Lawson flips from new vertex `p` (corner 0 of every stacked triangle)
    /// until each edge opposite it is Delaunay. Returns the flips, or the
    /// vertex within `min_angle` that a flip would have connected to `p`.
    fn make_delaunay(&mut self, p: VertexId) -> Result<u64, VertexId> {
        let pd = self.dirs[p as usize];
        let mut flips = 0;
        while let Some(t) = self.stack.pop() {
            // The far vertex comes with t, so its direction loads while
            // nothing else waits; the triangle across is read only to flip.
            let old_t = self.tris[t as usize];
            let Tri {
                v: [_, a, b],
                n: [across, n1, n2],
                o: [d, o1, o2],
            } = old_t;
            let (ad, bd, dd) = (self.dirs[a as usize], self.dirs[b as usize], self.dirs[d as usize]);
            if in_circle(pd, ad, bd, dd) <= 0.0 {
                continue;
            }
            // With every vertex in convex position this always holds; a fold
            // is refused rather than made.
            if side(pd, ad, dd) <= 0.0 || side(pd, dd, bd) <= 0.0 {
                self.stats.unflippable += 1;
                continue;
            }
            if chord2(pd, dd) <= self.min_chord2 {
                return Err(d);
            }
            // (p, a, b) + (d, b, a) become (p, a, d) in t and (p, d, b) in u.
            let (u, j) = (tri_of(across), index_of(across));
            let (j1, j2) = ((j + 1) % 3, (j + 2) % 3);
            let old_u = self.tris[u as usize];
            let (ua, ub) = (old_u.n[j1], old_u.n[j2]);
            // The next two tests need these, and their flips those.
            prefetch(&self.dirs[old_u.o[j1] as usize]);
            prefetch(&self.dirs[old_u.o[j2] as usize]);
            prefetch(&self.tris[tri_of(ua) as usize]);
            prefetch(&self.tris[tri_of(ub) as usize]);
            self.save(t, old_t);
            self.save(u, old_u);
            self.tris[t as usize] = Tri {
                v: [p, a, d],
                n: [ua, corner(u, 2), n2],
                o: [old_u.o[j1], b, o2],
            };
            self.tris[u as usize] = Tri {
                v: [p, d, b],
                n: [ub, n1, corner(t, 1)],
                o: [old_u.o[j2], o1, a],
            };
            self.link(ua, (corner(u, j1), b), (corner(t, 0), p));
            self.link(ub, (corner(u, j2), a), (corner(u, 0), p));
            self.link(n1, (corner(t, 1), a), (corner(u, 1), d));
            self.link(n2, (corner(t, 2), b), (corner(t, 2), d));
            // d is still in u.
            self.vert_tri[a as usize] = t;
            self.vert_tri[b as usize] = u;
            self.stack.push(t);
            self.stack.push(u);
            flips += 1;
        }
        Ok(flips)
    }

    /// Points neighbour link `at` (a corner) from `old` to `new`, each a
    /// (corner, far vertex) pair, without reading the triangle it is in.
    #[inline]
    fn link(&mut self, at: u32, old: (u32, VertexId), new: (u32, VertexId)) {
        if old == new {
            return;
        }
        if tri_of(at) < self.log_base {
            self.log.push(Change::Link { corner: at, old });
        }
        let tri = &mut self.tris[tri_of(at) as usize];
        tri.n[index_of(at)] = new.0;
        tri.o[index_of(at)] = new.1;
    }

    /// Logs triangle `t`, as `old`, before this insertion overwrites it (new
    /// slots need no log: undoing drops them).
    #[inline]
    fn save(&mut self, t: u32, old: Tri) {
        if t < self.log_base {
            self.log.push(Change::Tri(t, old));
        }
    }

    /// Takes the current insertion back: every change undone in reverse, the
    /// new slots and vertex dropped, every vertex of a restored triangle
    /// pointed at it again.
    fn undo(&mut self) {
        for change in self.log.iter().rev() {
            match *change {
                Change::Tri(t, old) => self.tris[t as usize] = old,
                Change::Link { corner, old } => {
                    let tri = &mut self.tris[tri_of(corner) as usize];
                    tri.n[index_of(corner)] = old.0;
                    tri.o[index_of(corner)] = old.1;
                }
            }
        }
        self.tris.truncate(self.log_base as usize);
        self.dirs.pop();
        self.vert_tri.pop();
        for change in &self.log {
            if let Change::Tri(t, _) = *change {
                for x in self.tris[t as usize].v {
                    self.vert_tri[x as usize] = t;
                }
            }
        }
        self.log.clear();
        self.stack.clear();
    }
}

// The ghosts are the first vertices, so a ghost id is a valid axis index.
const _: () = assert!(GHOSTS == AXES.len());
