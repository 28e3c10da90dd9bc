"""Run by Blender's Python (the ``bpy`` module), not imported by hairinv: builds the scene
:mod:`hairinv.export.render` describes and renders it to a PNG.

Usage: ``python _blender_scene.py SPEC.json``. The spec names an ``.npz`` of arrays, all in Blender's frame
(+Z up, metres): ``points`` (P, 3) and ``offsets`` (S + 1,) of the strands, ``radius`` (the strands' drawn
radius), ``body_vertices`` (V, 3) and ``body_faces`` (T, 3) (empty without a body); and the camera (its
location, the point it looks at, its lens), the sun's direction, the image size, the samples and the output
path. Only bpy and numpy are used (Blender's environment has no hairinv).
"""

import json
import sys

import bpy
import numpy as np
from mathutils import Vector


def _nodes(datablock):
    """The node tree of a new material or world (Blender 5 makes one; 4 needs ``use_nodes``, deprecated in 5)."""
    if datablock.node_tree is None:
        datablock.use_nodes = True
    return datablock.node_tree


def hair(spec, arrays, scene):
    """The strands as a Curves object (Cycles draws them as curve primitives) with a hair material."""
    offsets = arrays["offsets"]
    curves = bpy.data.hair_curves.new("hair")
    curves.add_curves([int(n) for n in np.diff(offsets)])
    curves.position_data.foreach_set("vector", np.ascontiguousarray(arrays["points"], dtype=np.float32).ravel())
    radius = curves.attributes.get("radius") or curves.attributes.new("radius", "FLOAT", "POINT")
    radius.data.foreach_set("value", np.full(len(arrays["points"]), float(arrays["radius"]), dtype=np.float32))
    material = bpy.data.materials.new("hair")
    tree = _nodes(material)
    nodes = tree.nodes
    nodes.clear()
    bsdf = nodes.new("ShaderNodeBsdfHairPrincipled")
    bsdf.parametrization = "MELANIN"
    bsdf.inputs["Melanin"].default_value = spec["melanin"]
    bsdf.inputs["Roughness"].default_value = 0.35
    out = nodes.new("ShaderNodeOutputMaterial")
    tree.links.new(bsdf.outputs[0], out.inputs["Surface"])
    curves.materials.append(material)
    scene.collection.objects.link(bpy.data.objects.new("hair", curves))


def body(arrays, scene):
    """The body as a smooth grey mesh."""
    vertices, faces = arrays["body_vertices"], arrays["body_faces"]
    if len(faces) == 0:
        return
    mesh = bpy.data.meshes.new("body")
    mesh.from_pydata(vertices.tolist(), [], faces.tolist())
    mesh.polygons.foreach_set("use_smooth", np.ones(len(faces), dtype=bool))
    material = bpy.data.materials.new("body")
    principled = _nodes(material).nodes["Principled BSDF"]
    principled.inputs["Base Color"].default_value = (0.55, 0.55, 0.55, 1.0)
    principled.inputs["Roughness"].default_value = 0.6
    mesh.materials.append(material)
    scene.collection.objects.link(bpy.data.objects.new("body", mesh))


def camera_and_light(spec, scene):
    data = bpy.data.cameras.new("camera")
    data.lens = spec["lens_mm"]
    data.sensor_fit = "HORIZONTAL"
    data.sensor_width = spec["sensor_mm"]
    camera = bpy.data.objects.new("camera", data)
    camera.location = Vector(spec["camera"])
    camera.rotation_mode = "QUATERNION"
    camera.rotation_quaternion = (Vector(spec["target"]) - camera.location).to_track_quat("-Z", "Y")
    scene.collection.objects.link(camera)
    scene.camera = camera
    sun = bpy.data.lights.new("sun", "SUN")
    sun.energy = 3.5
    sun.angle = 0.2
    light = bpy.data.objects.new("sun", sun)
    light.rotation_mode = "QUATERNION"
    light.rotation_quaternion = (-Vector(spec["sun"])).to_track_quat("-Z", "Y")
    scene.collection.objects.link(light)
    world = bpy.data.worlds.new("world")
    background = _nodes(world).nodes["Background"]
    background.inputs["Color"].default_value = (0.22, 0.23, 0.25, 1.0)
    background.inputs["Strength"].default_value = 1.0
    scene.world = world


def main(spec_path):
    with open(spec_path) as fh:
        spec = json.load(fh)
    arrays = dict(np.load(spec["arrays"]))
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    hair(spec, arrays, scene)
    body(arrays, scene)
    camera_and_light(spec, scene)
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = spec["samples"]
    scene.cycles.use_denoising = spec["denoise"]
    if spec["denoise"]:
        scene.cycles.denoiser = "OPENIMAGEDENOISE"
        scene.cycles.denoising_prefilter = "FAST"
        scene.cycles.denoising_quality = "FAST"
    scene.cycles.max_bounces = spec["bounces"]
    scene.render.threads_mode = "FIXED" if spec["threads"] else "AUTO"
    if spec["threads"]:
        scene.render.threads = spec["threads"]
    scene.render.resolution_x, scene.render.resolution_y = spec["size"]
    scene.render.resolution_percentage = 100
    scene.render.image_settings.file_format = "PNG"
    scene.render.image_settings.color_mode = "RGB"
    scene.render.dither_intensity = 0.0  # no noise added to the 8-bit colours
    scene.render.filepath = spec["output"]
    bpy.ops.render.render(write_still=True)
    print(json.dumps({"blender": bpy.app.version_string}))


if __name__ == "__main__":
    main(sys.argv[-1])
