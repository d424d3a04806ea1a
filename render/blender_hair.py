"""hairdigi hair colour for Blender: a Principled Hair BSDF (Chiang, absorption coefficient).

Written by ``hairdigi export --format blender``; needs Blender (tested: the ``bpy`` 5.0.1 package).

- In Blender (Text Editor > Run Script, or ``blender -P THIS.py``): builds the material and assigns
  it to the selected hair objects (Curves, legacy curves, or meshes with hair particles).
- ``python THIS.py -- --scene RIG.json --blend OUT.blend``, with a Python that has ``bpy``: also
  builds hairdigi's swatch rig (holder, three lights, camera, the swatch's strands as a Curves groom)
  and saves it ready to render; ``--render OUT.json --spp N`` renders it in Cycles and writes the
  mean linear Rec.709 colour.

``LOOK`` holds the values: ``sigma_a`` per fibre radius in linear Rec.709, roughness as Mitsuba's,
and Offset = minus Mitsuba's cuticle tilt (Cycles tilts the other way for curves drawn root to tip).
Only bpy and the standard library are used.
"""
import argparse
import json
import math
import sys
import time

LOOK = {}


def build_material(look=None):
    """The Principled Hair BSDF material of ``look`` (a new material, or the one of that name rebuilt)."""
    import bpy   # deferred: bpy exists only inside Blender, which runs this script

    look = look or LOOK
    mat = bpy.data.materials.get(look["name"]) or bpy.data.materials.new(look["name"])
    mat.use_nodes = True
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    nodes.clear()
    hair = nodes.new("ShaderNodeBsdfHairPrincipled")
    hair.model = look["model"]
    hair.parametrization = look["parametrization"]
    for name, value in look["inputs"].items():
        socket = next(s for s in hair.inputs if s.name == name)   # inputs[name] misses some in 5.0
        if socket.type == "RGBA" and len(value) == 3:
            value = list(value) + [1.0]
        socket.default_value = value
    out = nodes.new("ShaderNodeOutputMaterial")
    out.location = (300, 0)
    links.new(hair.outputs["BSDF"], out.inputs["Surface"])
    mat["hairdigi"] = json.dumps(look)
    return mat


def _takes_material(obj):
    if obj.type in ("CURVES", "CURVE"):
        return True
    return obj.type == "MESH" and any(ps.settings.type == "HAIR" for ps in obj.particle_systems)


def assign_to_selected(mat):
    """Give ``mat`` to every selected hair object; returns their names."""
    import bpy   # deferred: bpy exists only inside Blender, which runs this script

    names = []
    for obj in getattr(bpy.context, "selected_objects", []) or []:
        if not _takes_material(obj):
            continue
        if obj.type == "MESH":
            for ps in obj.particle_systems:
                if mat.name not in obj.data.materials:
                    obj.data.materials.append(mat)
                ps.settings.material_slot = mat.name
        else:
            obj.data.materials.clear()
            obj.data.materials.append(mat)
        names.append(obj.name)
    return names


def _quad(name, corners, material):
    import bpy   # deferred: bpy exists only inside Blender, which runs this script

    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata([tuple(c) for c in corners], [], [(0, 1, 2, 3)])
    obj = bpy.data.objects.new(name, mesh)
    mesh.materials.append(material)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def _diffuse(name, albedo):
    import bpy   # deferred: bpy exists only inside Blender, which runs this script

    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    bsdf = mat.node_tree.nodes.new("ShaderNodeBsdfDiffuse")
    bsdf.inputs["Color"].default_value = (albedo, albedo, albedo, 1.0)
    mat.node_tree.links.new(bsdf.outputs["BSDF"], mat.node_tree.nodes["Material Output"].inputs["Surface"])
    return mat


def _emission(name, radiance):
    import bpy   # deferred: bpy exists only inside Blender, which runs this script

    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    nodes = mat.node_tree.nodes
    for node in list(nodes):
        if node.type != "OUTPUT_MATERIAL":
            nodes.remove(node)
    emit = nodes.new("ShaderNodeEmission")
    emit.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    emit.inputs["Strength"].default_value = radiance
    mat.node_tree.links.new(emit.outputs["Emission"], nodes["Material Output"].inputs["Surface"])
    return mat


def build_rig(rig, mat):
    """hairdigi's swatch rig from ``rig`` (hairdigi's JSON): holder, lights, camera and the groom."""
    # deferred: bpy exists only inside Blender, which runs this script
    import bpy
    from mathutils import Matrix

    scene = bpy.context.scene
    for obj in list(bpy.data.objects):   # the start-up file's cube, light and camera
        bpy.data.objects.remove(obj)
    world = bpy.data.worlds.new("black")
    world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Strength"].default_value = float(rig.get("sky", 0.0))
    scene.world = world
    holder = rig["holder"]
    _quad("holder", holder["corners"], _diffuse("holder", holder["albedo"]))
    for i, light in enumerate(rig["lights"]):
        _quad(f"light{i}", light["corners"], _emission(f"light{i}", light["radiance"]))
    strands = rig["strands"]
    curves = bpy.data.hair_curves.new("swatch")
    curves.add_curves(strands["counts"])
    curves.attributes["position"].data.foreach_set("vector", strands["points"])
    radius = curves.attributes.get("radius") or curves.attributes.new("radius", "FLOAT", "POINT")
    radius.data.foreach_set("value", strands["radii"])
    curves.materials.append(mat)
    groom = bpy.data.objects.new("swatch", curves)
    scene.collection.objects.link(groom)
    cam = rig["camera"]
    data = bpy.data.cameras.new("camera")
    data.sensor_fit = "HORIZONTAL"
    data.angle = math.radians(cam["fov_deg"])
    data.clip_start, data.clip_end = 0.01, 100.0
    camera = bpy.data.objects.new("camera", data)
    left, up, forward, origin = cam["left"], cam["up"], cam["forward"], cam["origin"]
    camera.matrix_world = Matrix([[-left[i], up[i], -forward[i], origin[i]] for i in range(3)] + [[0, 0, 0, 1]])
    scene.collection.objects.link(camera)
    scene.camera = camera
    width, height = rig["size"]
    scene.render.resolution_x, scene.render.resolution_y, scene.render.resolution_percentage = width, height, 100
    scene.render.engine = "CYCLES"
    cycles = scene.cycles
    cycles.device = "CPU"
    depth = rig["max_depth"]
    cycles.max_bounces = depth
    for kind in ("diffuse", "glossy", "transmission", "volume"):
        setattr(cycles, f"{kind}_bounces", depth)
    cycles.transparent_max_bounces = depth
    cycles.sample_clamp_direct = cycles.sample_clamp_indirect = 0.0
    cycles.blur_glossy = 0.0
    cycles.caustics_reflective = cycles.caustics_refractive = True
    cycles.use_denoising = False
    cycles.use_adaptive_sampling = False
    cycles.filter_width = 0.01          # a box of one pixel, as Mitsuba's film
    scene.cycles_curves.shape = "THICK"
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0
    return groom


def render_mean(path, spp, seed=0, threads=0, want_pixels=False):
    """Render the scene in Cycles to an OpenEXR beside ``path`` and write its mean linear colour there
    (and, with ``want_pixels``, the linear RGB image, rows from the top)."""
    import bpy   # deferred: bpy exists only inside Blender, which runs this script

    scene = bpy.context.scene
    scene.cycles.samples = spp
    scene.cycles.seed = seed
    if threads:
        scene.render.threads_mode, scene.render.threads = "FIXED", threads
    exr = str(path) + ".exr"
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.image_settings.color_depth = "32"
    scene.render.filepath = exr
    start = time.perf_counter()
    bpy.ops.render.render(write_still=True)
    seconds = time.perf_counter() - start
    image = bpy.data.images.load(exr)
    pixels = list(image.pixels)
    n = len(pixels) // 4
    mean = [sum(pixels[c::4]) / n for c in range(3)]
    out = {"mean_linear": mean, "seconds": seconds, "spp": spp, "exr": exr, "blender": bpy.app.version_string}
    if want_pixels:
        width, height = image.size
        rows = [[pixels[4 * (y * width + x):4 * (y * width + x) + 3] for x in range(width)] for y in range(height)]
        out["pixels"] = rows[::-1]          # Blender's rows run from the bottom
    with open(path, "w") as f:
        json.dump(out, f)
    return mean


def main(argv):
    import bpy   # deferred: bpy exists only inside Blender, which runs this script

    parser = argparse.ArgumentParser(description="hairdigi hair material for Blender")
    parser.add_argument("--scene", help="hairdigi's swatch rig (JSON) to build around the material")
    parser.add_argument("--blend", help="save the .blend here")
    parser.add_argument("--render", help="render in Cycles and write the mean colour to this JSON")
    parser.add_argument("--spp", type=int, default=64)
    parser.add_argument("--threads", type=int, default=0)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--pixels", action="store_true", help="with --render: also write the image's pixels")
    args = parser.parse_args(argv)
    mat = build_material()
    if args.scene:
        with open(args.scene) as f:
            build_rig(json.load(f), mat)
    else:
        names = assign_to_selected(mat)
        print(f"hairdigi: material {mat.name!r} assigned to {', '.join(names) or 'no selected hair object'}")
    if args.blend:
        bpy.ops.wm.save_as_mainfile(filepath=args.blend)
    if args.render:
        render_mean(args.render, args.spp, seed=args.seed, threads=args.threads, want_pixels=args.pixels)


def script_args(argv):
    """Our arguments: after ``--`` (``blender -P THIS.py -- ...``), or a plain Python's own."""
    if "--" in argv:
        return argv[argv.index("--") + 1:]
    own = argv[1:]
    return own if any(a.startswith("--") for a in own) else []   # blender -P THIS.py: Blender's, not ours


if __name__ == "__main__":
    main(script_args(sys.argv))
