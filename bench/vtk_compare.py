#!/usr/bin/env python3
"""umbra's volume renderer against VTK's volume mappers, on the same machine, in one run.

For each case (a volume) and image size, renders the same emission-absorption scene with
`umbra render` (methods `ea` and `combined`, each a separate process: `--frames N
--timings-json`, `total_ms` = the median frame's submit-to-completion time) and, back to back
in this process, with VTK's vtkFixedPointVolumeRayCastMapper (CPU, threads = --threads) and
vtkGPUVolumeRayCastMapper (OpenGL; on a machine without a GPU, Mesa's llvmpipe), each timed as
the median of N `renderWindow.Render()` + `WaitForCompletion()` (glFinish) calls after one
warm-up render (which uploads the volume, compiles shaders, builds tables; its time is kept as
`first_ms`). The rounds (`--rounds`) repeat the whole umbra/VTK block so that a neighbour's
load on a shared machine falls on every peer alike; the median over rounds is reported.

Writes into the output directory (`-o`):
  results.csv    case, size, peer, ms, ratio (= ms / the VTK CPU mapper's ms, same case and
                 size: umbra/VTK-CPU for the umbra rows), then first_ms, cpu_ms (CPU time per
                 frame, all threads), rounds_ms, notes
  agreement.csv  mean absolute differences (8-bit sRGB) between umbra ea, VTK CPU, VTK GL
  <case>_<size>_montage.png   umbra ea | VTK CPU | VTK GL, side by side
  <case>_<size>_<peer>.png    each image; <case>_<size>_diff.png: |umbra ea - VTK CPU| x 4
  <case>.toml    the umbra scene (explicit look-at camera and transfer points)
  report.md      the markdown table that is also printed
and, with --sampling-check, sampling.csv: the last case (headsq by default) under VTK's
mappers at sample distances 2d, d, d/2 (time, ray-casting time, change of the image).

The same scene on both sides:
  * World frame: umbra places the volume by its NIfTI affine (NRRD: its spacings and space
    origin); the script reads that affine from `umbra info` and gives the vtkVolume the user
    matrix that maps VTK's data coordinates (origin + spacing * index) onto it, so index ->
    world is the same on both sides (checked against vtkNIFTIImageReader's sform/qform).
  * Camera: umbra's orbit convention (occlusion/src/camera.rs: azimuth 0 looks along +y, 90
    along +x, elevation 90 looks down from +z, distance in bounding-sphere radii of the world
    box) is evaluated here and given to both as an explicit eye, target, up (+z; -z for headsq,
    whose z runs downwards) and vertical
    fov_y (umbra `camera.eye/target/up/fov_y`; vtkCamera SetPosition/SetFocalPoint/SetViewUp/
    SetViewAngle; the clipping range reset to the volume).
  * Sampling: d = half the smallest voxel spacing (umbra's default): umbra
    `render.slice_distance = d` (view-aligned slices, the count rounded so they span the
    volume: the printed distance may differ in the 4th digit; a ray's step is d / cos(angle
    to the view axis), at most ~7 % longer in the image corners at fov 35); VTK
    SetSampleDistance(d) with AutoAdjustSampleDistances off (fixed point: also
    ImageSampleDistance 1 = one ray per pixel, min/max image sample distance 1; GPU: no
    jittering, sample distance not locked to the input spacing).
  * Transfer function: a ramp over the data's range (umbra's `umbra info` range): extinction
    sigma (1/world unit) 0 up to `lo`, rising linearly to `sigma_max` at `hi`; colour linear
    in RGB from `c0` at `lo` to `c1` at `hi`; constant beyond. umbra gets it as
    `[volume.transfer] points` (colour + extinction per world unit, alpha = 1 - exp(-sigma l)
    for a step of length l). VTK's scalar opacity is an opacity per ScalarOpacityUnitDistance,
    corrected per sample as 1 - (1 - a)^(step / unit): with the unit distance 1 world unit and
    a(v) = 1 - exp(-sigma(v)) this is exactly 1 - exp(-sigma step). Since VTK interpolates the
    opacity (not sigma) linearly between its points, the opacity function gets --tf-points
    points sampled from 1 - exp(-sigma(v)). Colours are unassociated on both sides (VTK and
    umbra composite alpha * colour front to back); no shading on either (umbra `ea`; VTK
    ShadeOff), trilinear interpolation, background composited under the volume.
  * Colour space: umbra composites in linear RGB and writes sRGB-encoded PNGs. VTK composites
    the same linear values into an 8-bit framebuffer without encoding; its images are
    sRGB-encoded here after reading back (outside the timing), so all panels are comparable.
  * Anti-aliasing: umbra's FXAA and MSAA are off by default (VTK does neither; no geometry in
    the scene); --fxaa turns FXAA back on. VTK windows get SetMultiSamples(0).
  * umbra `combined` is timed but is a different image (volumetric occlusion); only `ea` is
    compared with VTK's images.

Setup (VTK is not a dependency of the repository; use a venv):
    python3 -m venv /tmp/vtkb/venv
    /tmp/vtkb/venv/bin/pip install vtk numpy pillow      # vtk 9.x wheels from PyPI
    apt-get install -y xvfb                              # for the OpenGL mapper, if no X
    cargo build --release                                # target/release/umbra

The OpenGL mapper needs an X server: with DISPLAY unset the script starts `Xvfb -displayfd`
itself (and stops it at exit); without Xvfb it falls back to VTK offscreen rendering
(SetOffScreenRendering(1): EGL/OSMesa in the PyPI wheel), and if that cannot create a
context either, only the CPU mapper runs (said in the notes). --offscreen forces offscreen.
llvmpipe and lavapipe threads: LP_NUM_THREADS is set to --threads unless already set.

Usage:
    XDG_RUNTIME_DIR=/tmp /tmp/vtkb/venv/bin/python bench/vtk_compare.py -o /tmp/vtkb/out \\
        [--umbra target/release/umbra] [--cases mni,headsq] [--volume PATH ...] \\
        [--ramp 0.25,1.0] [--sigma S] [--view 120,15] [--sizes 512] [--frames 3] \\
        [--rounds 1] [--methods ea,combined] [--peers cpu,gl] [--threads 2] \\
        [--sampling-check] [--fxaa] [--offscreen] [--clip NX,NY,NZ]

--clip cuts the volume on both sides by one plane through the centre of its world box (umbra
`[[clip]]`, VTK `AddClippingPlane` with the normal reversed: VTK keeps the side its normal
points to); the images are compared as without it.
"""
import argparse
import atexit
import csv
import gc
import json
import math
import os
import re
import resource
import shutil
import statistics
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)

# name: (path relative to the repo, lo, hi as fractions of the data range, sigma_max per world
# unit, c0, c1 (linear RGB), azimuth, elevation, distance in bounding-sphere radii, up).
# headsq's z runs from the top of the head down (VTK's examples view it with up = -z).
CASES = {
    "mni": ("datasets/mni/mni_icbm152_t1_tal_nlin_sym_09a.nii.gz", 0.25, 1.0, 0.3,
            (0.35, 0.06, 0.03), (1.0, 0.9, 0.75), 120.0, 15.0, 2.8, (0.0, 0.0, 1.0)),
    "headsq": ("datasets/vtk/headsq_64x64x93.nhdr", 0.12, 0.6, 0.2,
               (0.35, 0.06, 0.03), (1.0, 0.9, 0.75), 30.0, -15.0, 2.8, (0.0, 0.0, -1.0)),
}
FOV_Y = 35.0
BACKGROUND = (1.0, 1.0, 1.0)

PEER_LABEL = {"umbra-ea": "umbra ea", "umbra-combined": "umbra combined",
              "umbra-mip": "umbra mip", "umbra-minip": "umbra minip",
              "vtk-cpu": "VTK FixedPoint (CPU)", "vtk-gl": "VTK GPU (OpenGL)"}


def peer_label(peer):
    """A peer's name in the tables: umbra-ea@gpu -> umbra ea (render.device = gpu)."""
    if peer in PEER_LABEL:
        return PEER_LABEL[peer]
    base, _, device = peer.partition("@")
    return "%s (render.device = %s)" % (PEER_LABEL.get(base, base), device)


# Stops the Xvfb this script started (set by ensure_display).
XVFB_STOP = None


def die(msg):
    sys.stderr.write("vtk_compare: " + msg + "\n")
    sys.stdout.flush()
    sys.stderr.flush()
    # Without unwinding: VTK's windows would be destroyed after their X server, which ends
    # the process with "XIO: fatal IO error" instead of this message's status.
    if XVFB_STOP is not None:
        XVFB_STOP()
    os._exit(2)


def import_deps():
    try:
        import numpy  # noqa: F401
    except ImportError:
        die("numpy is missing. Set up a venv: python3 -m venv /tmp/vtkb/venv && "
            "/tmp/vtkb/venv/bin/pip install vtk numpy pillow, then run this script with "
            "/tmp/vtkb/venv/bin/python")
    try:
        import PIL  # noqa: F401
    except ImportError:
        die("pillow is missing: pip install pillow (in the venv that has vtk)")
    try:
        import vtkmodules.all  # noqa: F401
    except ImportError as e:
        die("VTK is missing or broken (%s). Install it into a venv: python3 -m venv "
            "/tmp/vtkb/venv && /tmp/vtkb/venv/bin/pip install vtk numpy pillow, and run "
            "this script with /tmp/vtkb/venv/bin/python" % e)


# ---------------------------------------------------------------------------- display

def ensure_display(force_offscreen, notes):
    """Returns True for on-screen windows (an X display), False for VTK offscreen."""
    if force_offscreen:
        notes.append("VTK offscreen rendering (--offscreen)")
        return False
    if os.environ.get("DISPLAY"):
        return True
    xvfb = shutil.which("Xvfb")
    if not xvfb:
        notes.append("DISPLAY unset and no Xvfb: VTK offscreen rendering")
        return False
    r, w = os.pipe()
    proc = subprocess.Popen([xvfb, "-displayfd", str(w), "-screen", "0", "2200x2200x24",
                             "-nolisten", "tcp", "+extension", "GLX"],
                            pass_fds=(w,), stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    os.close(w)

    def stop():
        if proc.poll() is None:
            proc.terminate()
            try:
                proc.wait(5)
            except subprocess.TimeoutExpired:
                proc.kill()
    atexit.register(stop)
    global XVFB_STOP
    XVFB_STOP = stop
    buf = b""
    t0 = time.time()
    os.set_blocking(r, False)
    while time.time() - t0 < 20 and proc.poll() is None:
        try:
            chunk = os.read(r, 64)
        except BlockingIOError:
            chunk = None
        if chunk:
            buf += chunk
            if b"\n" in buf:
                break
        elif chunk == b"":
            break
        time.sleep(0.05)
    os.close(r)
    num = buf.decode().strip()
    if proc.poll() is not None or not num.isdigit():
        err = proc.stderr.read().decode(errors="replace")[-500:] if proc.poll() is not None else ""
        stop()
        notes.append("Xvfb failed to start (%s): VTK offscreen rendering" % err.strip())
        return False
    os.environ["DISPLAY"] = ":" + num
    notes.append("started Xvfb on :%s" % num)
    return True


# ---------------------------------------------------------------------------- umbra

def umbra_info(umbra, path):
    out = subprocess.run([umbra, "info", path], capture_output=True, text=True,
                         env=umbra_env())
    if out.returncode != 0:
        die("umbra info %s failed:\n%s" % (path, out.stderr))
    t = out.stdout
    num = r"[-+]?\d+(?:\.\d+)?(?:[eE][-+]?\d+)?"
    info = {"text": t}

    def search(pattern, what):
        m = re.search(pattern, t)
        if m is None:
            die("%s: no %s in `umbra info`'s report (a %s that is not finite, or a file "
                "that is not one scalar volume?):\n%s" % (path, what, what, t))
        return m
    fm = re.search(r"field:\s*(\S+) \((\d+) component", t)
    if fm and fm.group(2) != "1":
        die("%s: field '%s' has %s components: VTK's mappers here take one scalar per voxel "
            "(umbra convert --field %s:magnitude -o one.nrrd)" % (path, fm.group(1),
                                                                fm.group(2), fm.group(1)))
    m = search(r"dims:\s*(\d+) x (\d+) x (\d+)", "grid size")
    info["dims"] = [int(x) for x in m.groups()]
    m = search(r"spacing:\s*(%s),\s*(%s),\s*(%s)" % (num, num, num), "spacing")
    info["spacing"] = [float(x) for x in m.groups()]
    rows = re.findall(r"^\s*\[\s*(%s)\s+(%s)\s+(%s)\s+(%s)\s*\]" % ((num,) * 4), t, re.M)
    info["affine"] = [[float(x) for x in r] for r in rows[:4]]
    m = search(r"bounds:\s*min \((%s), (%s), (%s)\)\s*max \((%s), (%s), (%s)\)" % ((num,) * 6), "bounds")
    b = [float(x) for x in m.groups()]
    info["bounds"] = (b[:3], b[3:])
    m = search(r"range:\s*(%s) \.\. (%s)" % (num, num), "value range")
    info["range"] = (float(m.group(1)), float(m.group(2)))
    if not info["range"][1] > info["range"][0]:
        die("%s: every sample has the value %g: no ramp to place" % (path, info["range"][0]))
    if len(info["affine"]) != 4:
        die("could not read the affine from `umbra info %s`:\n%s" % (path, t))
    return info


def umbra_env():
    env = dict(os.environ)
    env.setdefault("XDG_RUNTIME_DIR", "/tmp")
    return env


def run_umbra(umbra, scene, out_png, method, w, h, d, frames, fxaa, tjson):
    # "ea@gpu": the method on one device (render.device); plain "ea": the default (auto).
    method, _, device = method.partition("@")
    cmd = [umbra, "render", scene, "-o", out_png, "--method", method,
           "--width", str(w), "--height", str(h), "--frames", str(frames),
           "--timings-json", tjson, "--set", "render.slice_distance=%r" % d]
    if fxaa:
        cmd += ["--set", "render.fxaa=true"]
    if device:
        cmd += ["--set", 'render.device="%s"' % device]
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    p = subprocess.run(cmd, capture_output=True, text=True, env=umbra_env())
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    if p.returncode != 0:
        die("umbra render failed (%s):\n%s" % (" ".join(cmd), p.stderr))
    with open(tjson) as f:
        t = json.load(f)
    # CPU seconds of the whole process (all threads); per frame: less the setup's wall time
    # (about one core), over the timed frames and the one more frame that measures passes.
    cpu = (r1.ru_utime + r1.ru_stime) - (r0.ru_utime + r0.ru_stime)
    nfr = len(t.get("frames_ms", [])) + (1 if t.get("passes") else 0)
    t["cpu_ms_per_frame"] = 1e3 * max(cpu - t.get("setup_seconds", 0.0), 0.0) / max(nfr, 1)
    return t, p.stderr.strip()


def toml_list(v):
    return "[" + ", ".join("%.9g" % x for x in v) + "]"


def write_scene(path, vol, cam, tf, fxaa, clip=None):
    head = """background = %s
[camera]
eye = %s
target = %s
up = %s
fov_y = %.9g
[volume]
path = %s
""" % (toml_list(BACKGROUND), toml_list(cam["eye"]), toml_list(cam["target"]),
       toml_list(cam["up"]), cam["fov_y"], json.dumps(vol))
    tail = """[render]
method = "%s"
width = 512
height = 512
msaa = 1
fxaa = %s
"""
    fx = "true" if fxaa else "false"
    if "window" in tf:
        txt = ("# Written by bench/vtk_compare.py --blend: the projection VTK renders too.\n"
               + head + "window = %s\ncolormap = \"grey\"\nopacity = %.9g\n"
               % (toml_list(tf["window"]), tf["opacity"]) + tail % ("mip", fx))
    else:
        pts = ",\n  ".join("{ value = %.9g, color = %s, extinction = %.9g }"
                           % (v, toml_list(c), s) for v, c, s in tf["umbra_points"])
        txt = ("# Written by bench/vtk_compare.py: the scene VTK renders too (explicit look-at "
               "camera).\n" + head + "[volume.transfer]\npoints = [\n  %s,\n]\n" % pts
               + tail % ("ea", fx))
    if clip is not None:
        # umbra keeps normal . x <= offset.
        txt += "[[clip]]\nnormal = %s\noffset = %.9g\n" % (toml_list(clip[0]), clip[1])
    with open(path, "w") as f:
        f.write(txt)


# ---------------------------------------------------------------------------- scene maths

def orbit_camera(bounds, az, el, dist, fov, up):
    lo, hi = bounds
    c = [(a + b) / 2 for a, b in zip(lo, hi)]
    r = math.sqrt(sum(((b - a) / 2) ** 2 for a, b in zip(lo, hi)))
    a, e = math.radians(az), math.radians(el)
    fwd = [math.sin(a) * math.cos(e), math.cos(a) * math.cos(e), -math.sin(e)]
    eye = [c[i] - fwd[i] * dist * r for i in range(3)]
    return {"eye": eye, "target": c, "up": list(up), "fov_y": fov}


def ramp(rng, lo_f, hi_f, sigma, c0, c1, n_vtk):
    vmin, vmax = rng
    lo = vmin + lo_f * (vmax - vmin)
    hi = vmin + hi_f * (vmax - vmin)
    up = [(vmin, c0, 0.0), (lo, c0, 0.0), (hi, c1, sigma)]
    if vmax > hi:
        up.append((vmax, c1, sigma))
    if vmin >= lo:
        up = up[1:]

    def sig(v):
        if v <= lo:
            return 0.0
        if v >= hi:
            return sigma
        return sigma * (v - lo) / (hi - lo)
    opac = [(vmin, 0.0)] if vmin < lo else []
    for k in range(n_vtk):
        v = lo + (hi - lo) * k / (n_vtk - 1)
        opac.append((v, 1.0 - math.exp(-sig(v))))
    if vmax > hi:
        opac.append((vmax, 1.0 - math.exp(-sigma)))
    return {"umbra_points": up, "vtk_opacity": opac,
            "vtk_color": [(lo, c0), (hi, c1)], "lo": lo, "hi": hi, "sigma": sigma}


def srgb_to_linear(v):
    return v / 12.92 if v <= 0.04045 else ((v + 0.055) / 1.055) ** 2.4


def projection_tf(rng, lo_f, hi_f, opacity):
    """--blend mip/minip: umbra's projection of `volume.window` [lo, hi] through the `grey`
    colour map (256 sRGB greys, decoded to linear, interpolated linearly) with opacity
    `volume.opacity`, nothing at or below lo; VTK gets the same 256 colours and an opacity 0
    up to lo, `opacity` from a millionth of the window past it (VTK's projections look the
    extreme value up in both functions, without a unit-distance correction)."""
    vmin, vmax = rng
    lo = vmin + lo_f * (vmax - vmin)
    hi = vmin + hi_f * (vmax - vmin)
    cols = [(lo + (hi - lo) * k / 255.0, (srgb_to_linear(k / 255.0),) * 3) for k in range(256)]
    eps = 1e-6 * (hi - lo)
    opac = [(min(vmin, lo - eps), 0.0), (lo, 0.0), (lo + eps, opacity), (max(vmax, hi), opacity)]
    return {"umbra_points": [], "window": (lo, hi), "opacity": opacity, "vtk_opacity": opac,
            "vtk_color": cols, "lo": lo, "hi": hi, "sigma": opacity}


# ---------------------------------------------------------------------------- VTK

class VtkPeer:
    """One render window with one volume mapper (kind 'cpu' or 'gl')."""

    def __init__(self, kind, image, user_matrix, tf, cam, d, threads, onscreen, blend="composite",
                 clip=None):
        import vtkmodules.all as vtk
        self.vtk = vtk
        self.kind = kind
        self.ren = vtk.vtkRenderer()
        self.ren.SetBackground(*BACKGROUND)
        self.win = vtk.vtkRenderWindow()
        self.win.SetMultiSamples(0)
        if not onscreen:
            self.win.SetOffScreenRendering(1)
        self.win.AddRenderer(self.ren)
        self.win.SetWindowName("vtk_compare " + kind)
        if kind == "cpu":
            m = vtk.vtkFixedPointVolumeRayCastMapper()
            m.SetNumberOfThreads(threads)
            m.SetImageSampleDistance(1.0)
            m.SetMinimumImageSampleDistance(1.0)
            m.SetMaximumImageSampleDistance(1.0)
            m.SetInteractiveSampleDistance(d)
            m.IntermixIntersectingGeometryOff()
            self.raycast = []
            self._t = None

            def start(*_):
                self._t = time.perf_counter()

            def end(*_):
                self.raycast.append((time.perf_counter() - self._t) * 1e3)
            m.AddObserver(vtk.vtkCommand.VolumeMapperRenderStartEvent, start)
            m.AddObserver(vtk.vtkCommand.VolumeMapperRenderEndEvent, end)
        else:
            m = vtk.vtkGPUVolumeRayCastMapper()
            m.SetUseJittering(0)
            m.SetLockSampleDistanceToInputSpacing(0)
            self.raycast = None
        m.SetAutoAdjustSampleDistances(0)
        m.SetSampleDistance(d)
        if blend == "mip":
            m.SetBlendModeToMaximumIntensity()
        elif blend == "minip":
            m.SetBlendModeToMinimumIntensity()
        else:
            m.SetBlendModeToComposite()
        m.SetInputData(image)
        if clip is not None:
            # VTK keeps the side a clipping plane's normal points to (world coordinates):
            # umbra's kept side normal . x <= offset is VTK's plane with the normal reversed.
            (n, off) = clip
            nn = sum(x * x for x in n)
            plane = vtk.vtkPlane()
            plane.SetOrigin(*[x * off / nn for x in n])
            plane.SetNormal(*[-x for x in n])
            m.AddClippingPlane(plane)
        self.mapper = m

        prop = vtk.vtkVolumeProperty()
        prop.ShadeOff()
        prop.SetInterpolationTypeToLinear()
        prop.SetScalarOpacityUnitDistance(1.0)
        ctf = vtk.vtkColorTransferFunction()
        ctf.SetColorSpaceToRGB()
        for v, c in tf["vtk_color"]:
            ctf.AddRGBPoint(v, *c)
        otf = vtk.vtkPiecewiseFunction()
        for v, a in tf["vtk_opacity"]:
            otf.AddPoint(v, a)
        prop.SetColor(ctf)
        prop.SetScalarOpacity(otf)
        self.prop = prop

        vol = vtk.vtkVolume()
        vol.SetMapper(m)
        vol.SetProperty(prop)
        um = vtk.vtkMatrix4x4()
        for i in range(4):
            for j in range(4):
                um.SetElement(i, j, user_matrix[i][j])
        vol.SetUserMatrix(um)
        self.ren.AddVolume(vol)
        self.volume = vol

        camera = vtk.vtkCamera()
        camera.SetPosition(*cam["eye"])
        camera.SetFocalPoint(*cam["target"])
        camera.SetViewUp(*cam["up"])
        camera.OrthogonalizeViewUp()
        camera.SetViewAngle(cam["fov_y"])
        self.ren.SetActiveCamera(camera)

    def resize(self, w, h):
        self.win.SetSize(w, h)
        self.ren.ResetCameraClippingRange()

    def render(self):
        c0, t0 = time.process_time(), time.perf_counter()
        self.win.Render()
        self.win.WaitForCompletion()
        self.last_cpu_ms = (time.process_time() - c0) * 1e3
        return (time.perf_counter() - t0) * 1e3

    def grab(self):
        """The window's RGB as uint8 rows top-down (linear values as in the framebuffer)."""
        import numpy as np
        from vtkmodules.util import numpy_support as ns
        w2i = self.vtk.vtkWindowToImageFilter()
        w2i.SetInput(self.win)
        w2i.SetInputBufferTypeToRGB()
        w2i.ReadFrontBufferOff()
        w2i.Update()
        img = w2i.GetOutput()
        w, h, _ = img.GetDimensions()
        a = ns.vtk_to_numpy(img.GetPointData().GetScalars()).reshape(h, w, -1)
        return np.ascontiguousarray(a[::-1, :, :3])

    def capabilities(self):
        try:
            return self.win.ReportCapabilities()
        except Exception:
            return ""

    def close(self):
        try:
            self.win.Finalize()
        except Exception:
            pass


def vtk_read(path):
    import vtkmodules.all as vtk
    low = path.lower()
    if low.endswith(".nii") or low.endswith(".nii.gz"):
        r = vtk.vtkNIFTIImageReader()
    elif low.endswith(".nhdr") or low.endswith(".nrrd"):
        r = vtk.vtkNrrdReader()
    elif low.endswith(".vti"):
        r = vtk.vtkXMLImageDataReader()
    elif low.endswith(".mhd") or low.endswith(".mha"):
        r = vtk.vtkMetaImageReader()
    elif low.endswith(".vtk"):
        r = vtk.vtkStructuredPointsReader()
    elif low.endswith(".slc"):
        r = vtk.vtkSLCReader()
    else:
        die("no VTK reader chosen for %s (NIfTI, NRRD, VTI, MetaImage, legacy VTK or SLC)" % path)
    r.SetFileName(path)
    r.Update()
    img = vtk.vtkImageData()
    img.DeepCopy(r.GetOutput())
    if img.GetNumberOfPoints() == 0:
        die("VTK read nothing from %s" % path)
    if img.GetPointData().GetScalars() is None or \
            img.GetPointData().GetScalars().GetNumberOfComponents() != 1:
        die("%s: VTK's mappers here take one scalar component per voxel" % path)
    # Index -> world is the user matrix's (umbra's affine, direction included): the data
    # keep origin + spacing * index, as `user_matrix_for` assumes.
    if hasattr(img, "SetDirectionMatrix"):
        img.SetDirectionMatrix(1, 0, 0, 0, 1, 0, 0, 0, 1)
    reader_matrix, qfac = None, 1.0
    if isinstance(r, vtk.vtkNIFTIImageReader):
        qfac = r.GetQFac()
        m = r.GetSFormMatrix() or r.GetQFormMatrix()
        if m is not None:
            reader_matrix = [[m.GetElement(i, j) for j in range(4)] for i in range(4)]
    return img, reader_matrix, qfac


def matmul(a, b):
    return [[sum(a[i][k] * b[k][j] for k in range(4)) for j in range(4)] for i in range(4)]


def user_matrix_for(img, affine):
    """M with M (origin + spacing * index) = affine index."""
    o, s = img.GetOrigin(), img.GetSpacing()
    inv = [[0.0] * 4 for _ in range(4)]  # data -> index
    for i in range(3):
        inv[i][i] = 1.0 / s[i]
        inv[i][3] = -o[i] / s[i]
    inv[3][3] = 1.0
    return matmul(affine, inv)


# ---------------------------------------------------------------------------- images

def srgb_encode(u8):
    import numpy as np
    x = u8.astype(np.float64) / 255.0
    y = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)
    return np.clip(np.round(y * 255.0), 0, 255).astype(np.uint8)


def load_png(path):
    import numpy as np
    from PIL import Image
    return np.asarray(Image.open(path).convert("RGB"))


def save_png(a, path):
    from PIL import Image
    Image.fromarray(a).save(path)


def montage(panels, labels, path):
    import numpy as np
    from PIL import Image, ImageDraw
    h = max(p.shape[0] for p in panels)
    strip = 18
    tiles = []
    for p, lab in zip(panels, labels):
        t = Image.new("RGB", (p.shape[1], h + strip), (255, 255, 255))
        t.paste(Image.fromarray(p), (0, strip))
        ImageDraw.Draw(t).text((4, 3), lab, fill=(0, 0, 0))
        tiles.append(np.asarray(t))
    gap = np.full((h + strip, 4, 3), 128, np.uint8)
    row = []
    for i, t in enumerate(tiles):
        if i:
            row.append(gap)
        row.append(t)
    save_png(np.concatenate(row, axis=1), path)


def compare(a, b):
    """Mean |a - b| over all pixels and over pixels where either is not background."""
    import numpy as np
    a16, b16 = a.astype(np.int16), b.astype(np.int16)
    diff = np.abs(a16 - b16)
    bg = np.array([round(255 * c) for c in BACKGROUND], np.int16)
    fg = (np.abs(a16 - bg).max(axis=2) > 3) | (np.abs(b16 - bg).max(axis=2) > 3)
    return {"mad_all": float(diff.mean()),
            "mad_fg": float(diff[fg].mean()) if fg.any() else 0.0,
            "p99_fg": float(np.percentile(diff[fg].max(axis=1), 99)) if fg.any() else 0.0,
            "fg_frac": float(fg.mean())}


# ---------------------------------------------------------------------------- main

def parse_size(s):
    if "x" in s:
        w, h = s.split("x")
        return int(w), int(h)
    return int(s), int(s)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("-o", "--out", required=True, help="output directory")
    ap.add_argument("--umbra", default=os.path.join(REPO, "target", "release", "umbra"))
    ap.add_argument("--cases", default=None,
                    help="of: " + ",".join(CASES) + " (default: both, or none with --volume)")
    ap.add_argument("--volume", action="append", default=[], metavar="PATH",
                    help="a volume of your own as a further case, named by its file name "
                         "(NIfTI, NRRD, VTI, MetaImage .mhd/.mha, legacy VTK .vtk, SLC .slc); repeatable")
    ap.add_argument("--ramp", default="0.25,1.0",
                    help="--volume cases: the ramp's lo,hi as fractions of the data range")
    ap.add_argument("--sigma", type=float, default=None,
                    help="--volume cases: extinction at the ramp's top per world unit "
                         "(default: 60 / the length of the volume's diagonal)")
    ap.add_argument("--view", default="120,15",
                    help="--volume cases: camera azimuth,elevation in degrees (umbra's orbit)")
    ap.add_argument("--sizes", default="512", help="comma list of N or WxH")
    ap.add_argument("--frames", type=int, default=3, help="timed frames per peer and round")
    ap.add_argument("--rounds", type=int, default=1)
    ap.add_argument("--methods", default="ea,combined",
                    help="umbra methods, each optionally @gpu or @cpu (render.device; "
                         "default auto: the CPU renderer draws ea on a CPU adapter)")
    ap.add_argument("--peers", default="cpu,gl", help="VTK mappers: cpu, gl")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--tf-points", type=int, default=65, help="VTK opacity points on the ramp")
    ap.add_argument("--fxaa", action="store_true", help="umbra FXAA on (default off)")
    ap.add_argument("--offscreen", action="store_true", help="VTK offscreen, no X server")
    ap.add_argument("--blend", default="composite", choices=["composite", "mip", "minip"],
                    help="composite: emission-absorption (umbra ea/combined); mip/minip: the "
                         "projections (umbra's methods of that name, VTK's blend modes), grey "
                         "over the case's ramp window, opacity --opacity")
    ap.add_argument("--opacity", type=float, default=1.0, help="--blend mip/minip: opacity")
    ap.add_argument("--clip", default=None, metavar="NX,NY,NZ",
                    help="one clipping plane with this normal through the volume's centre on "
                         "both sides (umbra keeps normal . x <= normal . centre; a leading "
                         "minus needs the = form: --clip=-1,0,0)")
    ap.add_argument("--sampling-check", action="store_true",
                    help="time VTK's mappers on the last case (headsq by default) at 2d, d, d/2")
    a = ap.parse_args()

    import_deps()
    import numpy as np
    os.environ.setdefault("LP_NUM_THREADS", str(a.threads))
    os.environ.setdefault("XDG_RUNTIME_DIR", "/tmp")
    umbra = os.path.abspath(a.umbra)
    if not os.access(umbra, os.X_OK):
        die("no umbra binary at %s (cargo build --release, or --umbra PATH)" % umbra)
    os.makedirs(a.out, exist_ok=True)
    notes = []
    load0 = os.getloadavg()
    onscreen = ensure_display(a.offscreen, notes)

    import vtkmodules.all as vtk
    vtk.vtkMultiThreader.SetGlobalMaximumNumberOfThreads(a.threads)
    vtk.vtkMultiThreader.SetGlobalDefaultNumberOfThreads(a.threads)
    vtk_version = vtk.vtkVersion.GetVTKVersion()
    if a.cases is None:
        a.cases = "" if a.volume else "mni,headsq"
    cases = [c.strip() for c in a.cases.split(",") if c.strip()]
    for c in cases:
        if c not in CASES:
            die("unknown case %s (of %s)" % (c, ", ".join(CASES)))
    cases_of = dict(CASES)
    try:
        lo_f, hi_f = (float(x) for x in a.ramp.split(","))
        az, el = (float(x) for x in a.view.split(","))
    except ValueError:
        die("--ramp and --view take two numbers each, as lo,hi and azimuth,elevation")
    if not 0.0 <= lo_f < hi_f <= 1.0:
        die("--ramp %s: lo and hi are fractions of the data range, 0 <= lo < hi <= 1" % a.ramp)
    clip_n = None
    if a.clip is not None:
        try:
            clip_n = [float(x) for x in a.clip.split(",")]
        except ValueError:
            clip_n = []
        if len(clip_n) != 3 or not all(math.isfinite(x) for x in clip_n) or not any(clip_n):
            die("--clip %s: a plane's normal, three finite numbers not all 0" % a.clip)
    if a.sigma is not None and not (a.sigma > 0 and math.isfinite(a.sigma)):
        die("--sigma %s: a positive extinction per world unit" % a.sigma)
    for vpath in a.volume:
        vpath = os.path.abspath(vpath)
        if not os.path.isfile(vpath):
            die("--volume %s: no such file" % vpath)
        name = re.sub(r"[^A-Za-z0-9_-]+", "_", re.sub(
            r"\.(nii\.gz|nii|nhdr|nrrd|vti|mhd|mha|vtk|slc)$", "", os.path.basename(vpath), flags=re.I))
        while name in cases_of:
            name += "_"
        # sigma None: from the volume's size, once `umbra info` has read it.
        cases_of[name] = (vpath, lo_f, hi_f, a.sigma, (0.35, 0.06, 0.03), (1.0, 0.9, 0.75),
                          az, el, 2.8, (0.0, 0.0, 1.0))
        cases.append(name)
    if not cases:
        die("no cases (--cases or --volume)")
    sizes = [parse_size(s) for s in a.sizes.split(",")]
    if a.blend != "composite" and a.methods == "ea,combined":
        a.methods = a.blend
    methods = [m.strip() for m in a.methods.split(",") if m.strip()]
    # The umbra image compared with VTK's: the first method's.
    main_peer = "umbra-" + methods[0]
    peers = [p.strip() for p in a.peers.split(",") if p.strip()]
    for p in peers:
        if p not in ("cpu", "gl"):
            die("unknown VTK peer %s (cpu, gl)" % p)

    meta = {"vtk": vtk_version, "umbra": umbra, "threads": a.threads,
            "LP_NUM_THREADS": os.environ.get("LP_NUM_THREADS"),
            "display": os.environ.get("DISPLAY") if onscreen else "offscreen",
            "nproc": os.cpu_count(), "gl": None, "adapter": None}
    rows, agree, case_notes = [], [], {}
    gl_ok = "gl" in peers
    for case in cases:
        rel, lo_f, hi_f, sigma, c0, c1, az, el, dist, up = cases_of[case]
        path = os.path.join(REPO, rel)
        info = umbra_info(umbra, path)
        if sigma is None:
            diag = math.dist(info["bounds"][0], info["bounds"][1])
            sigma = 60.0 / max(diag, 1e-12)
        d = 0.5 * min(info["spacing"])
        if a.blend == "composite":
            tf = ramp(info["range"], lo_f, hi_f, sigma, c0, c1, a.tf_points)
        else:
            tf = projection_tf(info["range"], lo_f, hi_f, a.opacity)
        cam = orbit_camera(info["bounds"], az, el, dist, FOV_Y, up)
        scene = os.path.join(os.path.abspath(a.out), case + ".toml")
        clip = None
        if clip_n is not None:
            bl, bh = info["bounds"]
            centre = [0.5 * (x + y) for x, y in zip(bl, bh)]
            clip = (clip_n, sum(n * c for n, c in zip(clip_n, centre)))
        write_scene(scene, path, cam, tf, a.fxaa, clip)
        img, reader_m, qfac = vtk_read(path)
        um = user_matrix_for(img, info["affine"])
        cn = []
        if reader_m is None and qfac < 0:
            cn.append("qfac -1 without a sform or qform matrix: VTK's reader may have "
                      "reversed the slices, the placement is unchecked")
        if reader_m is not None:
            # vtkNIFTIImageReader's sform/qform maps VTK data coordinates (origin + spacing
            # index) to NIfTI world: compose with index -> data and compare with umbra's.
            o, s = img.GetOrigin(), img.GetSpacing()
            d2i = [[s[0], 0, 0, o[0]], [0, s[1], 0, o[1]], [0, 0, s[2], o[2]], [0, 0, 0, 1]]
            v = matmul(reader_m, d2i)
            err = max(abs(v[i][j] - info["affine"][i][j]) for i in range(4) for j in range(4))
            cn.append("VTK reader sform/qform vs umbra affine: max |diff| %.3g" % err)
            # vtkNIFTIImageReader reverses the slices of a file with qfac = -1 (its data's k
            # is the file's nz - 1 - k): then its matrix is umbra's affine with k reversed,
            # and VTK's data are placed by the reader's matrix.
            nz = info["dims"][2]
            flip = [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, -1, nz - 1], [0, 0, 0, 1]]
            af = matmul(info["affine"], flip)
            err_k = max(abs(v[i][j] - af[i][j]) for i in range(4) for j in range(4))
            if err > 1e-3 and err_k <= 1e-3:
                um = reader_m
                cn.append("VTK's reader reversed the slices (qfac -1): VTK placed by its "
                          "sform/qform, umbra's affine with k reversed within %.3g" % err_k)
            elif err > 1e-3:
                cn.append("VTK's reader and umbra place the volume differently: images differ")
        vr = img.GetScalarRange()
        if abs(vr[0] - info["range"][0]) > 1e-6 or abs(vr[1] - info["range"][1]) > 1e-6:
            cn.append("value range differs: VTK %s, umbra %s" % (vr, info["range"]))
        case_notes[case] = cn
        print("== %s: dims %s spacing %s d=%.4g range %s, tf lo %.4g hi %.4g sigma %.4g"
              % (case, info["dims"], info["spacing"], d, info["range"], tf["lo"], tf["hi"],
                 sigma), flush=True)

        vpeers = {}
        for p in peers:
            if p == "gl" and not gl_ok:
                continue
            try:
                vpeers[p] = VtkPeer(p, img, um, tf, cam, d, a.threads, onscreen, a.blend, clip)
            except Exception as e:  # pragma: no cover
                notes.append("VTK %s mapper could not be set up: %s" % (p, e))
                if p == "gl":
                    gl_ok = False

        for (w, h) in sizes:
            size = "%dx%d" % (w, h)
            times = {}   # peer -> list of per-round medians
            firsts = {}
            cpus = {}
            extra = {}
            imgs = {}
            for rnd in range(a.rounds):
                for m in methods:
                    peer = "umbra-" + m
                    png = os.path.join(a.out, "%s_%s_%s.png" % (case, size, peer))
                    tj = os.path.join(a.out, "%s_%s_%s.json" % (case, size, peer))
                    t, err = run_umbra(umbra, scene, png, m, w, h, d, a.frames, a.fxaa, tj)
                    meta["adapter"] = t.get("adapter")
                    times.setdefault(peer, []).append(t["total_ms"])
                    cpus.setdefault(peer, []).append(t["cpu_ms_per_frame"])
                    firsts[peer] = 1e3 * t.get("setup_seconds", 0.0)
                    extra[peer] = "slices %s; passes %s" % (
                        t.get("slices"), ", ".join("%s %.0f" % kv for kv in sorted(
                            t.get("passes", {}).items(), key=lambda kv: -kv[1])))
                    if peer == main_peer:
                        imgs[main_peer] = load_png(png)
                    print("  %s %s round %d: %.1f ms (%s)" % (size, peer, rnd, t["total_ms"],
                                                             err.splitlines()[-1] if err else ""),
                          flush=True)
                for p, vp in list(vpeers.items()):
                    peer = "vtk-" + p
                    try:
                        vp.resize(w, h)
                        if vp.raycast is not None:
                            vp.raycast.clear()
                        first = vp.render()
                        if p == "gl" and meta["gl"] is None:
                            cap = vp.capabilities()
                            mm = re.search(r"OpenGL renderer string:\s*(.*)", cap)
                            mv = re.search(r"OpenGL version string:\s*(.*)", cap)
                            meta["gl"] = "%s; %s" % (mm.group(1).strip() if mm else "?",
                                                     mv.group(1).strip() if mv else "?")
                        ts, cs = [], []
                        for _ in range(a.frames):
                            ts.append(vp.render())
                            cs.append(vp.last_cpu_ms)
                    except Exception as e:
                        notes.append("VTK %s failed at %s: %s" % (p, size, e))
                        vp.close()
                        del vpeers[p]
                        continue
                    med = statistics.median(ts)
                    times.setdefault(peer, []).append(med)
                    cpus.setdefault(peer, []).append(statistics.median(cs))
                    firsts.setdefault(peer, first)
                    if vp.raycast:
                        rc = statistics.median(vp.raycast[1:] or vp.raycast)
                        extra[peer] = "ray casting %.0f ms of %.0f (rest: tables, texture, swap)" % (rc, med)
                    else:
                        extra[peer] = ""
                    print("  %s %s round %d: %.1f ms (first %.0f ms)" % (size, peer, rnd, med, first),
                          flush=True)
                    if rnd == 0:
                        im = srgb_encode(vp.grab())
                        if im.shape[0] != h or im.shape[1] != w:
                            notes.append("VTK %s image is %dx%d, asked %s" % (p, im.shape[1], im.shape[0], size))
                        imgs[peer] = im
                        save_png(im, os.path.join(a.out, "%s_%s_%s.png" % (case, size, peer)))
            cpu = statistics.median(times["vtk-cpu"]) if "vtk-cpu" in times else None
            for peer in [("umbra-" + m) for m in methods] + ["vtk-" + p for p in peers]:
                if peer not in times:
                    continue
                ms = statistics.median(times[peer])
                rows.append({"case": case, "size": size, "peer": peer, "ms": round(ms, 1),
                             "ratio": round(ms / cpu, 3) if cpu else "",
                             "first_ms": round(firsts.get(peer, 0.0), 1),
                             "cpu_ms": round(statistics.median(cpus[peer]), 1) if peer in cpus else "",
                             "rounds_ms": " ".join("%.1f" % x for x in times[peer]),
                             "notes": extra.get(peer, "")})
            order = [k for k in (main_peer, "vtk-cpu", "vtk-gl") if k in imgs]
            if order:
                montage([imgs[k] for k in order], [peer_label(k) for k in order],
                        os.path.join(a.out, "%s_%s_montage.png" % (case, size)))
            pairs = [(main_peer, "vtk-cpu"), (main_peer, "vtk-gl"), ("vtk-cpu", "vtk-gl")]
            for x, y in pairs:
                if x in imgs and y in imgs and imgs[x].shape == imgs[y].shape:
                    c = compare(imgs[x], imgs[y])
                    mean = lambda k: float(imgs[k].mean())
                    agree.append({"case": case, "size": size, "a": x, "b": y,
                                  "mean_a": round(mean(x), 2), "mean_b": round(mean(y), 2),
                                  **{k: round(v, 3) for k, v in c.items()}})
                    if (x, y) == (main_peer, "vtk-cpu"):
                        dimg = np.clip(np.abs(imgs[x].astype(np.int16) - imgs[y].astype(np.int16)) * 4,
                                       0, 255).astype(np.uint8)
                        save_png(255 - dimg, os.path.join(a.out, "%s_%s_diff.png" % (case, size)))

        if a.sampling_check and case == cases[-1]:
            samp = []
            for p, vp in vpeers.items():
                w, h = sizes[0]
                vp.resize(w, h)
                ref = None
                for f in (2.0, 1.0, 0.5):
                    vp.mapper.SetSampleDistance(d * f)
                    vp.render()
                    ts = [vp.render() for _ in range(a.frames)]
                    rc = statistics.median(vp.raycast[-a.frames:]) if vp.raycast else None
                    im = srgb_encode(vp.grab())
                    if f == 1.0:
                        ref = im
                    samp.append({"case": case, "peer": "vtk-" + p, "size": "%dx%d" % (w, h),
                                 "sample_distance": d * f, "ms": round(statistics.median(ts), 1),
                                 "raycast_ms": round(rc, 1) if rc else "", "im": im})
                vp.mapper.SetSampleDistance(d)
                for s in samp:
                    if s["peer"] == "vtk-" + p:
                        s["mad_vs_d"] = round(compare(s.pop("im"), ref)["mad_fg"], 3)
            with open(os.path.join(a.out, "sampling.csv"), "w", newline="") as f:
                wr = csv.DictWriter(f, fieldnames=["case", "peer", "size", "sample_distance",
                                                   "ms", "raycast_ms", "mad_vs_d"])
                wr.writeheader()
                wr.writerows(samp)
            print("sampling check (%s):" % case)
            for s in samp:
                print("  %(peer)s d=%(sample_distance).4g: %(ms)s ms (ray casting %(raycast_ms)s), "
                      "mean |diff| vs d %(mad_vs_d)s" % s)
        for vp in vpeers.values():
            vp.close()
        vpeers.clear()
        gc.collect()  # destroy the windows while the X server is up (observers make cycles)

    with open(os.path.join(a.out, "results.csv"), "w", newline="") as f:
        wr = csv.DictWriter(f, fieldnames=["case", "size", "peer", "ms", "ratio", "first_ms",
                                           "cpu_ms", "rounds_ms", "notes"])
        wr.writeheader()
        wr.writerows(rows)
    with open(os.path.join(a.out, "agreement.csv"), "w", newline="") as f:
        if agree:
            wr = csv.DictWriter(f, fieldnames=list(agree[0].keys()))
            wr.writeheader()
            wr.writerows(agree)

    md = ["| case | size | peer | ms | / VTK CPU | CPU ms | rounds ms | first render ms |",
          "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        md.append("| %s | %s | %s | %.1f | %s | %s | %s | %.0f |" % (
            r["case"], r["size"], peer_label(r["peer"]), r["ms"],
            ("%.2f" % r["ratio"]) if r["ratio"] != "" else "-",
            ("%.0f" % r["cpu_ms"]) if r["cpu_ms"] != "" else "-", r["rounds_ms"], r["first_ms"]))
    md.append("")
    md.append("VTK %s; umbra adapter: %s; VTK OpenGL: %s; threads %d (LP_NUM_THREADS %s); "
              "%s; %d CPUs; median of %d frames x %d round(s). first render: umbra = setup "
              "(load, upload) before its first frame; VTK = the warm-up Render(). CPU ms: CPU "
              "time (all threads) per frame, median over rounds (umbra: the process's, less its "
              "setup, over its frames; approximate)."
              % (meta["vtk"], meta["adapter"], meta["gl"], a.threads, meta["LP_NUM_THREADS"],
                 "X display " + str(meta["display"]) if onscreen else "offscreen",
                 meta["nproc"] or 0, a.frames, a.rounds))
    if agree:
        md += ["", "| case | size | images | mean |diff| (all px) | mean |diff| (volume px) | "
                   "p99 | volume px |", "|---|---|---|---|---|---|---|"]
        for g in agree:
            md.append("| %s | %s | %s vs %s | %.2f | %.2f | %.0f | %.1f%% |" % (
                g["case"], g["size"], peer_label(g["a"]), peer_label(g["b"]), g["mad_all"],
                g["mad_fg"], g["p99_fg"], 100 * g["fg_frac"]))
        md.append("")
        md.append("8-bit sRGB differences (0-255), max over channels for p99.")
    for c, cn in case_notes.items():
        for n in cn:
            md.append("- %s: %s" % (c, n))
    for n in notes:
        md.append("- " + n)
    md.append("- load average (1, 5, 15 min) at start %s, at end %s (a shared machine: other "
              "jobs' load falls on every peer; see rounds_ms in results.csv)"
              % (" ".join("%.2f" % x for x in load0), " ".join("%.2f" % x for x in os.getloadavg())))
    text = "\n".join(md) + "\n"
    with open(os.path.join(a.out, "report.md"), "w") as f:
        f.write(text)
    print()
    print(text)


if __name__ == "__main__":
    main()
    # VTK's windows go before the Xvfb this script started (stopped at exit): a window
    # destroyed after its server is gone ends the process with "XIO: fatal IO error".
    gc.collect()
