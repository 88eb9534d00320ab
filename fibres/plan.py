"""The decomposition plan: every discrete choice made once, reapplied to deformed copies.

Kohout et al. (GRAPP 2012) make several discrete choices per decomposition: the 5-degree
rotation of the box about the principal axis (§3.2), the planes of the sweep, the contour
vertex closest to the rectangle's first vertex and the split of the contour into four
parts (§3.3; here made continuous, see `fibres.slicing.correspondence`). Made afresh on every
frame of a motion (or on the poses q - h and q + h of a finite difference), any of them
can flip and fibre ``k`` would jump. A
`DecompositionPlan` records them on the rest-pose surface, in the muscle's own terms:

- the box orientation: the axis rule actually used ("attachments" or "covariance"), the
  reference direction ``v0`` of the rest pose and the winning rotation index; on a
  deformed copy ``v0`` is carried along by the best-fit rotation of the vertices (Kabsch,
  on at most `KABSCH_VERTICES` evenly strided vertices: exact for a rigid motion, smooth
  under deformation), the principal frame is re-derived
  and the same rotation applied, and the box is the vertices' bounding box in that frame;
- the slicing planes as fractions of the box height;
- per plane, the start point and the three split points of the contour (continuous
  quantities, not vertex indices: `fibres.slicing.correspondence` puts them on the contour curve,
  at the soft closest point to the rectangle corner and at the perimeter ratios), each
  frozen as a material point of the surface: the point lies on a contour segment between
  two mesh-edge crossings, so it is ``sum_k w_k V_k`` over those two edges' four end
  vertices (``anchor_vertices``, ``anchor_weights``); on a deformed copy of the same
  mesh it moves smoothly with the vertices (the topology is the same in every frame);
- the mesh topology itself (edges, face table), computed once.

What a deformed copy does per frame, and why the result is continuous
---------------------------------------------------------------------
No discrete choice is re-made. Every step is a continuous, piecewise smooth function of
the vertex positions:

- box: Kabsch rotation (SVD; smooth while the fit is non-degenerate), the plan's axis
  rule and rotation index, bounding box (min/max over vertices: continuous, piecewise
  smooth); plane heights = the plan's fractions x box height;
- sections: each contour point is the plane's intersection with a mesh edge, linear in the
  edge's end points; a plane passing a mesh vertex changes the number of contour points
  but not the contour as a curve (a segment shrinks to zero length);
- loop: where a plane cuts several loops, the loop carrying the plan's anchors (smallest
  summed squared distance to them, `fibres.slicing.contours.anchored_loops`) -- this only changes
  where two loops are equally near the anchors;
- correspondence points (`fibres.slicing.soft_anchor`): the anchors (material
  points, projected along the axis onto their planes) are placed on the contour at a *soft*
  closest point: a Gaussian-weighted mean arc position, the weights integrated exactly
  along each segment (so splitting a segment changes nothing) with a width proportional
  to the distance to the contour (near the contour it is the closest point). Where the
  plane has moved far through the material and two parts of the contour are about as
  near (measured: up to 25 mm on the LHDL iliacus at a 20-degree bend), the point moves
  smoothly between them instead of jumping. Split points are searched in tapered windows
  around their nominal arc places after the start, and put in order by a projection onto
  the ordered positions (isotonic regression, 1-Lipschitz; the identity on ordered
  input) -- never "chosen afresh";
- subdivision of the rectangle by arc-length ratios and the mean value coordinates of the
  template points: smooth in the contour points (MVC of a point with respect to the fixed
  rectangle's subdivision, which moves continuously).

Remaining discontinuities (measured on LHDL bend sweeps, ``tests/fibres/
test_decompose_lhdl.py``): a plane whose section changes topology (two loops merging or
splitting, an island appearing or vanishing, typically at the end planes).
`fibres.slicing.morph.anchored_maps` follows the whole section through such events
(`fibres.slicing.contours.bridge_loops`, for planes that cut one loop at rest,
`rest_loop_counts`) when the plan is passed to it (``plan=``).

Kohout's own software had the same idea: an optional rest-pose "InputTemplate".
"""
from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from .errors import InputError
from .fit.fitting import Box, _frame_for, _norm, cross3, principal_frame
from .slicing.planes import MeshTopology

__all__ = ["DecompositionPlan", "kabsch_rotation", "box_from_plan", "box_and_local",
           "rest_geometry", "rest_loop_counts"]


def _readonly(a, dtype=None):
    """A read-only copy of ``a`` (as ``dtype`` if given); an array that is already read-only,
    owns its data and has that dtype (one made here, passed on by `dataclasses.replace`) is
    kept as is."""
    if (isinstance(a, np.ndarray) and not a.flags.writeable and a.flags.owndata
            and (dtype is None or a.dtype == dtype)):
        return a
    a = np.array(a, dtype=dtype, copy=True)
    a.flags.writeable = False
    return a


@dataclass(frozen=True)
class DecompositionPlan:
    """Discrete choices of one decomposition, reusable on a deformed copy of the mesh.

    Attributes
    ----------
    topology : MeshTopology
        Faces, edges and face tables of the mesh (same topology required on reuse).
    rest_vertices : (V, 3) float
        Vertices of the surface the plan was made on (for the Kabsch rotation).
    v0 : (3,) float
        Reference cross-section direction used on ``rest_vertices``.
    axis_method : str
        "attachments" or "covariance" (the rule used, never "auto", so it cannot flip).
    angle_index : int
        Winning rotation of (v0, w0) about the axis.
    angle_step_deg : float
    fractions : (S,) float
        Slicing heights as fractions of the box height.
    choice : (S, 4) int64
        Per plane, the mesh edge crossed by the contour vertex nearest to the start point
        P0 and to the first points of the 2nd, 3rd and 4th parts of the contour (for
        information; the points themselves are the anchors).
    anchor_vertices : (S, 4, 4) int64
    anchor_weights : (S, 4, 4) float
        The same four points per plane as material points of the mesh,
        ``X = sum_k w_k V[v_k]`` (the end vertices of the two mesh edges whose crossings
        bound the contour segment carrying the point, weights ``(1 - tau)(1 - t_j)``,
        ``(1 - tau) t_j``, ``tau (1 - t_j+1)``, ``tau t_j+1``); on a deformed copy they are
        carried along with the vertices and re-inserted into the contours
        (`fibres.slicing.morph.anchored_maps`).
    template : fibres.template.templates.Template, optional
        The template whose attachment areas oriented the box (oblique templates such as
        pennate tilt the principal axis, `fibres.fit.fitting.principal_frame`).
    rest_origin, rest_insertion : (K, 3) float, optional
        The landmarks of the rest pose (metres), to make the attachment filter's choices on
        the rest pose when `filter_choice` does not cover a request.
    filter_choice : fibres.attachments.filtering.FilterChoice, optional
        The attachment filter's choices (Kohout 2012 §3.4) made on the rest pose for the
        fibres of the decomposition that made the plan; reapplied on deformed copies
        (`fibres.attachments.filtering.apply_filter`) so that trimming and reconstruction do not flip.
    """

    topology: MeshTopology
    rest_vertices: np.ndarray
    v0: np.ndarray
    axis_method: str
    angle_index: int
    angle_step_deg: float
    fractions: np.ndarray
    choice: np.ndarray
    anchor_vertices: np.ndarray
    anchor_weights: np.ndarray
    template: object = None
    rest_origin: np.ndarray | None = None
    rest_insertion: np.ndarray | None = None
    filter_choice: object = None

    def __post_init__(self):
        for name in ("rest_vertices", "v0", "fractions", "choice", "anchor_vertices",
                     "anchor_weights"):
            object.__setattr__(self, name, _readonly(getattr(self, name)))
        for name in ("rest_origin", "rest_insertion"):
            if getattr(self, name) is not None:
                value = _readonly(np.asarray(getattr(self, name), dtype=np.float64))
                if value.ndim != 2 or value.shape[1] != 3:
                    raise ValueError(f"{name} must be (K, 3), got {value.shape}")
                object.__setattr__(self, name, value)
        if self.axis_method not in ("attachments", "covariance"):
            raise ValueError(f"axis_method must be 'attachments' or 'covariance', "
                             f"got {self.axis_method!r}")
        n_s = self.fractions.size
        if self.choice.shape != (n_s, 4):
            raise ValueError("choice must be (S, 4) for S fractions")
        if self.anchor_vertices.shape != (n_s, 4, 4) or self.anchor_weights.shape != (n_s, 4, 4):
            raise ValueError("anchor_vertices and anchor_weights must be (S, 4, 4)")
        if self.rest_vertices.shape != (self.topology.n_vertices, 3):
            raise ValueError("rest_vertices do not match the topology")

    def __reduce__(self):
        # Template holds a mappingproxy (not picklable): pickle it as (name, params)
        state = {f.name: getattr(self, f.name) for f in fields(self)}
        state["template"] = template_spec(self.template)
        return (_unpickle_plan, (state,))

    @property
    def n_slices(self) -> int:
        """S, the number of slicing planes."""
        return int(self.fractions.size)

    def check_mesh(self, vertices, faces) -> None:
        """Raise InputError unless ``faces`` (and the vertex count) are the plan's mesh's."""
        faces = np.asarray(faces)
        if (len(vertices) != self.topology.n_vertices or faces.shape != self.topology.faces.shape
                or not np.array_equal(faces, self.topology.faces)):
            raise InputError(f"the mesh ({len(vertices)} vertices, {faces.shape[0]} faces) does "
                             "not have the topology the plan was made on "
                             f"({self.topology.n_vertices} vertices, "
                             f"{self.topology.faces.shape[0]} faces)", where="plan",
                             fix="Pass a deformed copy of the plan's mesh (same faces), or "
                                 "make a new plan (decompose without plan=).")


def template_spec(template):
    """(name, params dict) of a Template, or None: its picklable description."""
    return None if template is None else (template.name, dict(template.params))


def template_from_spec(spec):
    """The Template of `template_spec`'s description (or None)."""
    if spec is None:
        return None
    from .template.templates import get_template

    return get_template(spec[0], **spec[1])


def _unpickle_plan(state):
    state = dict(state)
    state["template"] = template_from_spec(state["template"])
    return DecompositionPlan(**state)


def kabsch_rotation(source, target) -> np.ndarray:
    """Best-fit rotation R (3, 3) with ``R @ (source_i - c_s) ~ target_i - c_t``.

    Kabsch (1976), "A solution for the best rotation to relate two sets of vectors",
    Acta Cryst. A32:922-923: SVD of the cross-covariance, with the reflection removed.

    Parameters
    ----------
    source, target : (V, 3) float
    """
    s = source - source.mean(axis=0)
    t = target - target.mean(axis=0)
    u, _, vt = np.linalg.svd(s.T @ t)
    d = np.sign(np.linalg.det(vt.T @ u.T)) or 1.0
    return vt.T @ np.diag([1.0, 1.0, d]) @ u.T


#: at most this many vertices (evenly spread over the vertex list) enter the Kabsch fit
KABSCH_VERTICES = 2000


def _kabsch_subset(n: int):
    """Vertex indices for the Kabsch fit: every vertex up to `KABSCH_VERTICES`, else an
    evenly strided subset (fixed by the topology, so exact for rigid motions and smooth)."""
    if n <= KABSCH_VERTICES:
        return slice(None)
    return np.linspace(0, n - 1, KABSCH_VERTICES).astype(np.int64)


def box_from_plan(plan: DecompositionPlan, vertices, origin, insertion) -> Box:
    """The template box of a deformed copy, with the plan's orientation (Kohout 2012 §3.2).

    The reference direction ``v0`` rides along with the muscle (Kabsch rotation from the
    plan's rest vertices), the principal frame is re-derived with the plan's axis rule,
    (v0, w0) is rotated by the plan's angle, and the box is the vertices' bounding box
    in that frame.

    Parameters
    ----------
    plan : DecompositionPlan
    vertices : (V, 3) float
    origin, insertion : (K, 3) float

    Returns
    -------
    Box
    """
    return box_and_local(plan, vertices, origin, insertion)[0]


def box_and_local(plan: DecompositionPlan, vertices, origin, insertion, *, vt=None):
    """`box_from_plan` and the vertices in the box frame, transposed; ``vt``: the (3, V)
    transposed vertices when at hand.

    Returns
    -------
    box : Box
    local_t : (3, V) float
        Rows x, y, z of every vertex in the box frame (``corner`` at the origin), for
        `fibres.slicing.planes.slice_mesh` (rows keep the reductions over V contiguous).
    """
    v = np.asarray(vertices, dtype=np.float64)
    vt = np.ascontiguousarray(v.T) if vt is None else vt              # (3, V)
    if v is plan.rest_vertices or np.array_equal(v, plan.rest_vertices):
        rot = np.eye(3)
    else:
        sub = _kabsch_subset(len(v))
        rot = kabsch_rotation(plan.rest_vertices[sub], v[sub])
    v_ref = rot @ plan.v0
    centroid = vt.mean(axis=1)
    u = None
    if plan.axis_method == "attachments" and not _oblique(plan.template):
        # Kohout 2012 §3.2 with the attachment direction (as principal_frame computes it)
        direction = np.mean(insertion, axis=0) - np.mean(origin, axis=0)
        dist = _norm(direction)
        if dist > 0:
            u = direction / dist
            v0, w0 = _frame_for(u, v_ref)       # the rule of fibres.fit.fitting.principal_frame
    if u is None:
        frame = principal_frame(v, origin, insertion, axis=plan.axis_method, v_ref=v_ref,
                                template=plan.template, angle_step_deg=plan.angle_step_deg,
                                angle_index=plan.angle_index)
        centroid, u, v0, w0 = frame.centroid, frame.axis, frame.v0, frame.w0
    theta = np.deg2rad(plan.angle_step_deg * plan.angle_index)
    x = np.cos(theta) * v0 + np.sin(theta) * w0
    y = cross3(u, x)
    axes = np.stack([x, y, u], axis=1)
    local_t = axes.T @ (vt - centroid[:, None])                       # (3, V)
    lo, hi = local_t.min(axis=1), local_t.max(axis=1)
    local_t -= lo[:, None]
    box = Box(centroid + axes @ lo, axes, hi - lo, plan.angle_index, plan.angle_step_deg,
              method=plan.axis_method)
    return box, local_t


def _oblique(template) -> bool:
    """Whether the template's attachment centroids are offset across the cube (pennate)."""
    return template is not None and template.oblique


def rest_geometry(plan: DecompositionPlan):
    """Rest-pose positions and normals for matching a plan's anchors materially.

    Computed once per plan and cached on the object (not a field: the frozen plan stays
    equal to itself).

    Returns
    -------
    rest : (V, 3) float
        The plan's rest vertices.
    normals : (V, 3) float
        Area-weighted vertex normals of the rest surface (outward for the outward-wound
        surfaces `decompose` works on).
    anchors : (S, 4, 3) float
        Rest positions of the four anchors of every plane, ``sum_k w_k V[v_k]``.
    anchor_normals : (S, 4, 3) float
        Their normals, interpolated the same way.
    """
    cached = plan.__dict__.get("_rest_geometry")
    if cached is not None:
        return cached
    v = plan.rest_vertices
    f = plan.topology.faces
    fn = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])     # 2 x area x normal
    normals = np.zeros_like(v)
    for c in range(3):
        np.add.at(normals, f[:, c], fn)
    normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-300)
    anchors = np.einsum("skn,sknd->skd", plan.anchor_weights, v[plan.anchor_vertices])
    anchor_normals = np.einsum("skn,sknd->skd", plan.anchor_weights,
                               normals[plan.anchor_vertices])
    out = tuple(_readonly(x) for x in (v, normals, anchors, anchor_normals))
    plan.__dict__["_rest_geometry"] = out
    return out


def rest_loop_counts(plan: DecompositionPlan):
    """(S,) int64: how many loops each plane cut on the plan's rest pose (-1: unknown, the
    plan has no rest landmarks). Computed once and cached on the plan.

    Where the rest plane cut one loop, the whole section of the muscle is that contour;
    on a deformed copy the same plane may cut several (the section pinches and splits, or
    passes a saddle), and `fibres.slicing.morph.anchored_maps` then bridges all of them into one
    contour, which is continuous through the topology change. Where the rest plane already
    cut several loops, only the one used at rest (and loops its anchors move onto) is
    followed."""
    cached = plan.__dict__.get("_rest_loop_counts")
    if cached is not None:
        return cached
    n_s = plan.n_slices
    if plan.rest_origin is None or plan.rest_insertion is None:
        counts = np.full(n_s, -1, dtype=np.int64)
    else:
        from .slicing.planes import slice_mesh

        box, local_t = box_and_local(plan, plan.rest_vertices, plan.rest_origin,
                                     plan.rest_insertion)
        tf = np.eye(4)
        tf[:3, :3] = box.axes
        tf[:3, 3] = box.corner
        sections = slice_mesh(plan.rest_vertices, plan.topology, tf,
                              plan.fractions * box.extents[2], local_t=local_t)
        counts = np.bincount(sections.loop_slice, minlength=n_s).astype(np.int64)
    counts = _readonly(counts)
    plan.__dict__["_rest_loop_counts"] = counts
    return counts
