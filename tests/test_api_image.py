"""The image the API returns: still the (H, W, 3) float32 array, displayed tone-mapped in a notebook
(``_repr_png_`` and ``rl.show`` give the PNG preview's sRGB pixels), with one-line reprs and ``spp=``
wherever a render starts."""

import pickle

import imageio.v3 as iio
import numpy as np
import pytest

import realistic as rl
from realistic.core.image_files import srgb_encode
from realistic.renderer.job import RenderJob
from realistic.renderer.output import write_preview

SMALL = {"resolution": (8, 6), "spp": 1, "lens_sampling": "rear", "dispersion": False}


@pytest.fixture(scope="module")
def rendered() -> rl.Image:
    return rl.render(rl.load_scene(**SMALL), backend="numpy", threads=1)


def test_render_returns_an_image_that_is_still_the_float32_array(rendered):
    assert isinstance(rendered, rl.Image) and isinstance(rendered, np.ndarray)
    assert rendered.shape == (6, 8, 3) and rendered.dtype == np.float32 and float(rendered.mean()) > 0
    # what is no longer an image is a plain array or scalar; what still is, stays one
    assert type(rendered.mean()) is np.float32 and repr(rendered[..., 1]) == repr(np.asarray(rendered)[..., 1])
    assert type(rendered.sum(axis=2)) is np.ndarray and isinstance(rendered * 2, rl.Image)
    assert type(np.asarray(rendered)) is np.ndarray
    np.testing.assert_array_equal(pickle.loads(pickle.dumps(rendered)), rendered)


def test_repr_png_is_the_png_preview_the_writer_gives(rendered, tmp_path):
    write_preview(tmp_path / "preview.png", np.asarray(rendered))
    written = iio.imread(tmp_path / "preview.png")
    shown = iio.imread(rendered._repr_png_())
    assert shown.shape == (6, 8, 3) and shown.dtype == np.uint8 and shown.max() > 0
    np.testing.assert_array_equal(shown, written)


def test_repr_png_of_a_slice_or_an_empty_image_is_left_to_numpy():
    image = rl.Image.of(np.full((4, 5, 3), 0.25, np.float32))
    assert image[0]._repr_png_() is None and rl.Image.of(np.zeros((0, 0, 3), np.float32))._repr_png_() is None
    assert repr(image[0, 0]) == repr(np.full(3, 0.25, np.float32))
    with pytest.raises(rl.UserError, match=r"\(height, width, 3\)"):
        rl.Image.of(np.zeros((4, 5)))


def test_show_draws_the_srgb_encoded_image_not_the_linear_values(rendered):
    matplotlib = pytest.importorskip("matplotlib")
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    linear = np.full((4, 6, 3), 0.25, np.float32)
    rl.show(linear, exposure=1.0)  # 0.25 x 2 = 0.5 linear: sRGB 188 of 255, where imshow of 0.25 shows 64
    drawn = plt.gca().images[0].get_array()
    assert round(float(srgb_encode(np.float32(0.5))) * 255) == 188
    assert drawn.shape == (4, 6, 3) and np.all(drawn == 188)
    plt.close("all")
    result = rl.render_job(RenderJob(rl.load_scene(**SMALL), (rl.load_scene(**SMALL).camera,), "numpy"),
                           rl.ThreadPasses(1))[0]
    fig, ax = plt.subplots()
    rl.show(result, ax=ax)
    np.testing.assert_array_equal(ax.images[0].get_array(), iio.imread(rl.Image.of(result.image)._repr_png_()))
    plt.close("all")
    with pytest.raises(rl.UserError, match="show takes"):
        rl.show(np.zeros((3, 3)))


def test_spp_is_honoured_by_render_and_render_job():
    scene = rl.load_scene(**SMALL)
    job = RenderJob(scene, (scene.camera, scene.camera), "numpy")
    results = rl.render_job(job, rl.ThreadPasses(1), spp=3)
    assert [r.samples_total for r in results] == [8 * 6 * 3] * 2 and [r.camera.spp for r in results] == [3, 3]
    with pytest.raises(rl.UserError, match="samples per pixel"):
        rl.render_job(job, spp=0)
    once, thrice = (rl.render(scene, backend="numpy", threads=1, spp=spp) for spp in (1, 3))
    assert not np.array_equal(once, thrice)  # more samples: another estimate


def test_reprs_are_one_line_summaries_without_arrays(rendered):
    scene = rl.load_scene(**SMALL)
    result = rl.render_job(RenderJob(scene, (scene.camera,), "numpy"), rl.ThreadPasses(1))[0]
    thin = rl.ThinLensCamera(45.0, 0.1, 3.0, 32, 24, 4, np.eye(4))
    texts = {"scene": repr(scene), "mesh": repr(scene.meshes[0]), "lens": repr(scene.camera.lens),
             "camera": repr(scene.camera), "thin": repr(thin), "result": repr(result), "image": repr(rendered)}
    for name, text in texts.items():
        assert "\n" not in text and "array" not in text and len(text) < 300, (name, text)
    assert texts["lens"].startswith("LensSystem('dgauss', 11 surfaces") and "8x6" in texts["camera"]
    assert texts["thin"] == "ThinLensCamera(fov 45 deg, 32x24, 4 spp, lens radius 0.1, focus 3)"
    assert texts["result"].startswith("RenderResult(frame 0, 8x6, complete") and texts["image"].startswith(
        "Image(8x6 float32, mean ")
    assert f"{len(scene.instances)} instances" in texts["scene"] and "LensCamera('dgauss'" in texts["scene"]
