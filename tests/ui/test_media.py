"""Media: list ten newest per kind (more on request), download, delete one or all; map upload."""

from __future__ import annotations

import io
import os
import re
import zipfile
from pathlib import Path

import pytest
from PIL import Image

from atemr.ui.media.files import MediaError, MediaStore, human_size


def fill(data_dir: Path, kind_dir: str, count: int, ext: str = ".jpg") -> list[str]:
    folder = data_dir / kind_dir
    folder.mkdir(parents=True, exist_ok=True)
    names = []
    for i in range(count):
        path = folder / f"capture-{i:02d}{ext}"
        path.write_bytes(b"\xff\xd8" + bytes([i]) * 10)
        os.utime(path, (1000 + i, 1000 + i))  # i larger = newer
        names.append(path.name)
    return names


def pgm_bytes(w: int = 20, h: int = 10) -> bytes:
    buf = io.BytesIO()
    Image.new("L", (w, h), 254).save(buf, format="PPM")
    return buf.getvalue()


MAP_YAML = b"image: room.pgm\nresolution: 0.05\norigin: [0.0, 0.0, 0.0]\noccupied_thresh: 0.65\n" \
           b"free_thresh: 0.196\nnegate: 0\n"


def data_dir(app) -> Path:
    return app.config["ATEMR_CONFIG"].data_dir


def test_list_ten_newest_then_more(alice, app, ui):
    fill(data_dir(app), "media/images", 13)
    html = alice.get("/media").get_data(as_text=True)
    assert "capture-12.jpg" in html and "capture-03.jpg" in html and "capture-02.jpg" not in html
    assert 'class="more"' in html
    more = alice.get("/api/media/images?offset=10").get_json()
    assert more["total"] == 13 and [f["name"] for f in more["files"]] == ["capture-02.jpg", "capture-01.jpg",
                                                                          "capture-00.jpg"]
    assert alice.get("/api/media/images?offset=x").status_code == 400
    assert alice.get("/api/media/secrets").status_code == 404


def test_download_and_delete_one(alice, app, ui):
    fill(data_dir(app), "media/images", 2)
    response = alice.get("/media/images/capture-01.jpg")
    assert response.status_code == 200 and response.data.startswith(b"\xff\xd8")
    assert "attachment" in response.headers["Content-Disposition"]
    response.close()
    ui.post(alice, "/media/images/capture-01.jpg/delete")
    assert not (data_dir(app) / "media/images/capture-01.jpg").exists()
    assert (data_dir(app) / "media/images/capture-00.jpg").exists()
    assert ui.post(alice, "/media/images/capture-01.jpg/delete").status_code == 404


def test_delete_all_of_one_kind(admin, app, ui):
    fill(data_dir(app), "media/images", 12)
    fill(data_dir(app), "media/videos", 2, ".mp4")
    ui.post(admin, "/media/images/delete-all")
    assert not list((data_dir(app) / "media/images").iterdir())
    assert len(list((data_dir(app) / "media/videos").iterdir())) == 2


def test_the_recording_being_written_is_listed_but_not_deleted(admin, app, gateway, ui):
    """The robot's recording keeps its current part open: deleting it lost that part for good (the writer went on
    into a file nobody could reach, whose disk space stayed taken until the part ended). It is listed as being
    recorded, refused one by one, and kept by DELETE ALL; the parts already closed go."""
    folder = data_dir(app) / "traces"
    folder.mkdir(parents=True, exist_ok=True)
    closed, current = folder / "run-20261126-145607.mcap", folder / "run-20261126-145607.1.mcap"
    for path in (closed, current):
        path.write_bytes(b"\x89MCAP0\r\n")
    gateway.in_use = [current]
    html = admin.get("/media").get_data(as_text=True)
    item = re.search(r'<li data-name="run-20261126-145607.1.mcap">.*?</li>', html, re.S)
    assert item is not None and "being recorded" in item.group(0) and "delete-one" not in item.group(0)
    listed = {f["name"]: f["in_use"] for f in admin.get("/api/media/traces").get_json()["files"]}
    assert listed == {closed.name: False, current.name: True}
    refused = ui.post(admin, f"/media/traces/{current.name}/delete")
    assert refused.status_code == 302 and current.exists()
    assert f"{current.name} is still being recorded" in admin.get("/media").get_data(as_text=True)
    ui.post(admin, "/media/traces/delete-all")
    assert not closed.exists() and current.exists()
    assert "Deleted 1 of the traces; kept the one still being recorded." in admin.get("/media").get_data(as_text=True)
    gateway.in_use = []  # the recording ended: now it may go
    ui.post(admin, f"/media/traces/{current.name}/delete")
    assert not current.exists()


@pytest.mark.parametrize("name", ["..%2F..%2Fusers.sqlite3", "..", ".hidden.jpg", "x.txt", "a%00.jpg",
                                  "capture-00.jpg%2F..%2F..%2Fui.key"])
def test_traversal_and_unlisted_names_are_refused(alice, app, ui, name):
    fill(data_dir(app), "media/images", 1)
    response = alice.get(f"/media/images/{name}")
    response.close()
    assert response.status_code == 404
    assert ui.post(alice, f"/media/images/{name}/delete").status_code in (404, 405)
    assert (data_dir(app) / "ui.key").exists()


@pytest.mark.parametrize(("size", "shown"), [(0, "0 bytes"), (640, "640 bytes"), (1000, "1.00 kB"), (12_345, "12.3 kB"),
                                             (99_950, "100 kB"), (999_500, "1.00 MB"), (58_893_312, "58.9 MB"),
                                             (1_200_000_000, "1.20 GB")])
def test_sizes_read_as_a_phone_says_them(size, shown):
    assert human_size(size) == shown


def test_a_listed_size_is_in_plain_units(alice, app, ui):
    folder = data_dir(app) / "traces"
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "run-20261126-145607.mcap").write_bytes(b"\0" * 58_893_312)  # was listed as "57513.0 KiB"
    assert "58.9 MB" in alice.get("/media").get_data(as_text=True)


def test_store_refuses_names_outside(tmp_path):
    store = MediaStore(tmp_path)
    with pytest.raises(MediaError):
        store.path("images", "../ui.key")
    with pytest.raises(MediaError, match="unknown media kind"):
        store.newest("secrets")


def write_map(folder: Path, name: str = "room") -> None:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / f"{name}.yaml").write_bytes(MAP_YAML.replace(b"room.pgm", f"{name}.pgm".encode()))
    (folder / f"{name}.pgm").write_bytes(pgm_bytes())


def test_maps_download_as_zip_and_delete_with_their_image(alice, app, gateway, ui):
    write_map(data_dir(app) / "maps")
    listing = alice.get("/api/media/maps").get_json()
    # stored maps first, then the map store's read-only built-in
    assert [(f["name"], f["builtin"]) for f in listing["files"]] == [("room.yaml", False), ("studio.yaml", True)]
    response = alice.get("/media/maps/room.yaml")
    assert response.headers["Content-Disposition"].endswith("room.zip")
    assert sorted(zipfile.ZipFile(io.BytesIO(response.data)).namelist()) == ["room.pgm", "room.yaml"]
    ui.post(alice, "/media/maps/room.yaml/delete")
    assert not list((data_dir(app) / "maps").iterdir())
    assert gateway.maps_changed_count == 1


def test_built_in_maps_cannot_be_deleted(admin, app, gateway, ui):
    write_map(data_dir(app) / "maps")
    assert ui.post(admin, "/media/maps/studio.yaml/delete").status_code == 404
    assert "studio" in app.extensions["atemr.maps"].names()
    ui.post(admin, "/media/maps/delete-all")  # every stored map, never a built-in
    assert not list((data_dir(app) / "maps").iterdir())
    assert app.extensions["atemr.maps"].names() == ["studio"]
    assert admin.get("/media/maps/studio.yaml").status_code == 200  # still downloadable


def test_the_dashboard_and_the_robot_share_one_map_store(alice, app, ui):
    store = app.extensions["atemr.maps"]
    assert app.extensions["atemr.media"].maps is store
    assert upload(alice, ui).status_code == 302
    assert store.names() == ["studio", "room"]
    assert store.load("room").data.shape == (10, 20)


def inline_error(response) -> str:
    """The refusal shown beside the upload form of the page the upload answered with."""
    match = re.search(r'<p class="error inline-error" id="map-upload-error" role="alert">(.*?)</p>',
                      response.get_data(as_text=True), re.S)
    assert match, "no error beside the upload form"
    return match.group(1)


def upload(client, ui, yaml_bytes=MAP_YAML, image=None, yaml_name="room.yaml", image_name="room.pgm"):
    data = {"yaml": (io.BytesIO(yaml_bytes), yaml_name),
            "image": (io.BytesIO(pgm_bytes() if image is None else image), image_name)}
    return ui.post(client, "/mapping/upload", data, content_type="multipart/form-data", follow_redirects=False)


def test_map_upload_validated_then_stored(alice, app, gateway, ui):
    response = upload(alice, ui)
    assert response.status_code == 302
    maps = data_dir(app) / "maps"
    assert sorted(p.name for p in maps.iterdir()) == ["room.pgm", "room.yaml"]
    assert gateway.maps_changed_count == 1
    # uploading the same name again does not overwrite
    again = upload(alice, ui)
    assert again.status_code == 409  # refused on the page itself, beside the upload form
    assert "a map named &#39;room&#39; exists already" in inline_error(again)


def test_map_upload_refused_by_the_map_reader_stores_nothing(alice, app, gateway, ui):
    response = upload(alice, ui, yaml_bytes=MAP_YAML.replace(b"free_thresh: 0.196", b"free_thresh: 0.9"))
    assert response.status_code == 400
    assert not [p for p in (data_dir(app) / "maps").iterdir()]  # nor a staging directory left behind
    page = inline_error(response)
    assert "free_thresh: must be below occupied_thresh" in page
    assert gateway.maps_changed_count == 0


def test_a_built_in_map_cannot_be_replaced_by_an_upload(alice, app, ui):
    yaml_bytes = MAP_YAML.replace(b"room.pgm", b"studio.pgm")
    response = upload(alice, ui, yaml_bytes=yaml_bytes, yaml_name="studio.yaml", image_name="studio.pgm")
    assert response.status_code == 400
    assert "built-in map" in inline_error(response)
    assert not list((data_dir(app) / "maps").iterdir())


def test_map_upload_size_limit_of_the_map_store(tmp_path, ui):
    from atemr.io.map_store import MapStore
    from atemr.ui.app import create_app

    store = MapStore(tmp_path / "data", max_upload_bytes=100)
    app = create_app(ui.make_config(tmp_path), None, hash_method=ui.FAST_SCRYPT, map_store=store)
    app.extensions["atemr.users"].set_password("admin", ui.ADMIN_PW)
    client = app.test_client()
    ui.login(client, "admin", ui.ADMIN_PW)
    response = upload(client, ui)
    assert response.status_code == 400
    assert "larger than the limit of 100" in inline_error(response)
    assert store.names() == ["studio"]


@pytest.mark.parametrize(("kwargs", "message"), [
    ({"yaml_name": "room.txt"}, "must be a .yaml"),
    ({"image_name": "room.exe"}, "map image must be"),
    ({"yaml_bytes": b"image: other.pgm\nresolution: 0.05\n"}, "must be one of the uploaded files"),
    ({"yaml_bytes": b"image: ../../ui.key\n"}, "must be one of the uploaded files"),
    ({"yaml_bytes": b"a: 1\na: 2\n"}, "duplicate key"),
    ({"yaml_bytes": b"!!python/object:os.system {}\n"}, "unsafe or unknown tag refused"),
    ({"image": b""}, "neither may be empty"),
])
def test_bad_map_uploads_are_refused_and_store_nothing(alice, app, gateway, ui, kwargs, message):
    response = upload(alice, ui, **kwargs)
    assert response.status_code == 400
    assert gateway.maps_changed_count == 0
    assert message in inline_error(response).replace("&#39;", "'")
    assert not list((data_dir(app) / "maps").iterdir())  # nothing stored, no staging directory left


def test_upload_names_go_through_secure_filename(alice, app, gateway, ui):
    yaml_bytes = MAP_YAML.replace(b"room.pgm", b"etc_room.pgm")
    upload(alice, ui, yaml_bytes=yaml_bytes, yaml_name="../../etc/room.yaml", image_name="../etc/room.pgm")
    assert sorted(p.name for p in (data_dir(app) / "maps").iterdir()) == ["etc_room.pgm", "etc_room.yaml"]


def test_upload_size_limit(tmp_path, gateway, ui):
    from atemr.ui.app import create_app

    app = create_app(ui.make_config(tmp_path, max_upload_mb=0.01), gateway, hash_method=ui.FAST_SCRYPT)
    app.extensions["atemr.users"].set_password("admin", ui.ADMIN_PW)
    client = app.test_client()
    ui.login(client, "admin", ui.ADMIN_PW)
    response = upload(client, ui, image=b"P5 " + b"0" * 20_000)
    assert response.status_code == 413


def test_without_a_robot_uploads_are_checked_by_the_package_map_reader(tmp_path, ui):
    pytest.importorskip("atemr.io.sim.maps", reason="the ROS map reader (atemr/io/sim/maps.py) has not landed")
    from atemr.ui.app import create_app

    app = create_app(ui.make_config(tmp_path), None, hash_method=ui.FAST_SCRYPT)
    app.extensions["atemr.users"].set_password("admin", ui.ADMIN_PW)
    client = app.test_client()
    ui.login(client, "admin", ui.ADMIN_PW)
    assert upload(client, ui).status_code == 302
    bad = MAP_YAML.replace(b"free_thresh: 0.196", b"free_thresh: 0.9").replace(b"room.pgm", b"bad.pgm")
    assert upload(client, ui, yaml_bytes=bad, yaml_name="bad.yaml", image_name="bad.pgm").status_code == 400
    assert sorted(p.name for p in (app.config["ATEMR_CONFIG"].data_dir / "maps").iterdir()) == \
        ["room.pgm", "room.yaml"]


# -- playable videos, thumbnails, delete that asks first ----------------------------------------------------
def write_video(path: Path, value: int = 120, fmt=None) -> None:
    """A real two-frame video (MP4/H.264 unless told) of one grey level."""
    import numpy as np

    from atemr.io.video_file import MP4_H264, VideoWriter

    path.parent.mkdir(parents=True, exist_ok=True)
    writer = VideoWriter(path, fmt or MP4_H264, 10.0)
    for i in range(2):
        writer.write(np.full((240, 320, 3), value, dtype=np.uint8), i * 0.1)
    writer.close()


def write_jpeg(path: Path, size: tuple[int, int], color: tuple[int, int, int]) -> bytes:
    buf = io.BytesIO()
    Image.new("RGB", size, color).save(buf, format="JPEG")
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(buf.getvalue())
    return buf.getvalue()


def test_videos_download_with_their_type_and_mp4_plays_in_place(alice, app):
    videos = data_dir(app) / "media/videos"
    write_video(videos / "video-1.mp4")
    old = write_jpeg(videos / "video-0.mjpeg", (64, 48), (0, 0, 255)) * 3  # the recorder's old format
    (videos / "video-0.mjpeg").write_bytes(old)
    response = alice.get("/media/videos/video-1.mp4")
    response.close()
    assert response.mimetype == "video/mp4" and "attachment" in response.headers["Content-Disposition"]
    response = alice.get("/media/videos/video-0.mjpeg")
    data = response.data
    response.close()
    assert response.mimetype == "video/x-motion-jpeg" and "attachment" in response.headers["Content-Disposition"]
    assert data == old
    # in place: inline, with byte ranges (a <video> seeks with them)
    response = alice.get("/media/videos/video-1.mp4/view", headers={"Range": "bytes=0-99"})
    data = response.data
    response.close()
    assert response.status_code == 206 and response.mimetype == "video/mp4" and len(data) == 100
    assert response.headers["Content-Disposition"].startswith("inline")
    assert response.headers["Content-Range"].startswith("bytes 0-99/")
    for refused in ("/media/videos/video-0.mjpeg/view", "/media/maps/studio.yaml/view"):  # no browser shows them
        response = alice.get(refused)
        response.close()
        assert response.status_code == 404
    html = alice.get("/media").get_data(as_text=True)
    assert '<video class="thumb"' in html and 'src="/media/videos/video-1.mp4/view"' in html
    assert 'poster="/media/videos/video-1.mp4/thumbnail.jpg"' in html
    assert "plays in VLC or ffplay, not in a browser" in html  # said of the .mjpeg only
    assert html.count("plays in VLC or ffplay") == 1


def thumbnail(client, kind: str, name: str) -> Image.Image:
    response = client.get(f"/media/{kind}/{name}/thumbnail.jpg")
    data = response.data
    response.close()
    assert response.status_code == 200 and response.mimetype == "image/jpeg", response.status_code
    return Image.open(io.BytesIO(data))


def test_thumbnails_of_images_and_videos_are_small_made_once_and_cached(alice, app, monkeypatch):
    from atemr.ui.media import thumbnails

    write_jpeg(data_dir(app) / "media/images/big.jpg", (1600, 1200), (200, 30, 30))
    write_video(data_dir(app) / "media/videos/clip.mp4", value=90)
    write_jpeg(data_dir(app) / "media/videos/old.mjpeg", (640, 480), (30, 200, 30))
    made: list[str] = []
    preview = thumbnails.preview
    monkeypatch.setattr(thumbnails, "preview", lambda source: made.append(source.name) or preview(source))
    image = thumbnail(alice, "images", "big.jpg")
    assert image.size == (320, 240) and image.getpixel((5, 5))[0] > 180
    video = thumbnail(alice, "videos", "clip.mp4")
    assert video.size == (320, 240) and abs(video.getpixel((5, 5))[0] - 90) < 8
    assert thumbnail(alice, "videos", "old.mjpeg").getpixel((5, 5))[1] > 180
    thumbnail(alice, "images", "big.jpg")
    assert made == ["big.jpg", "clip.mp4", "old.mjpeg"]  # the second request is served from the cache
    cache = data_dir(app) / "cache/thumbnails"
    assert len(list(cache.glob("*.jpg"))) == 3
    # a file replaced under the same name gets a new thumbnail, and the old one goes
    write_jpeg(data_dir(app) / "media/images/big.jpg", (400, 300), (30, 30, 200))
    os.utime(data_dir(app) / "media/images/big.jpg", (5000, 5000))
    assert thumbnail(alice, "images", "big.jpg").getpixel((5, 5))[2] > 180
    assert len(list(cache.glob("*.jpg"))) == 3


def test_a_file_that_cannot_be_previewed_gets_a_no_preview_tile(alice, app, monkeypatch, caplog):
    from atemr.ui.media import thumbnails

    (data_dir(app) / "media/videos").mkdir(parents=True)
    (data_dir(app) / "media/videos/broken.mp4").write_bytes(b"\x00" * 100)
    tile = thumbnail(alice, "videos", "broken.mp4")
    assert tile.size == (320, 240) and tile.getpixel((5, 5)) == pytest.approx((60, 60, 60), abs=4)
    assert "no thumbnail for videos broken.mp4: cannot read broken.mp4" in caplog.text
    # an image too large to decode on the robot is judged from its header
    write_jpeg(data_dir(app) / "media/images/huge.jpg", (64, 48), (250, 250, 250))
    monkeypatch.setattr(thumbnails, "MAX_PREVIEW_PIXELS", 64 * 48 - 1)
    assert thumbnail(alice, "images", "huge.jpg").getpixel((5, 5)) == pytest.approx((60, 60, 60), abs=4)
    assert "huge.jpg is 64×48, too large to preview" in caplog.text
    assert alice.get("/media/maps/studio.yaml/thumbnail.jpg").status_code == 404
    assert alice.get("/media/videos/missing.mp4/thumbnail.jpg").status_code == 404


def test_the_thumbnail_cache_is_bounded_and_forgets_deleted_media(alice, app, ui):
    store = app.extensions["atemr.media"]
    store.thumbnails.max_files = 3
    for i in range(5):
        write_jpeg(data_dir(app) / f"media/images/capture-{i}.jpg", (64, 48), (i * 40, 0, 0))
        os.utime(data_dir(app) / f"media/images/capture-{i}.jpg", (1000 + i, 1000 + i))
        thumbnail(alice, "images", f"capture-{i}.jpg")
    cache = data_dir(app) / "cache/thumbnails"
    assert len(list(cache.glob("*.jpg"))) == 3
    ui.post(alice, "/media/images/capture-4.jpg/delete")
    assert len(list(cache.glob("*.jpg"))) == 2


def test_deleting_one_file_asks_first_on_the_page_and_in_more(alice, app):
    fill(data_dir(app), "media/images", 12)
    html = alice.get("/media").get_data(as_text=True)
    assert 'data-confirm="Delete capture-11.jpg? This cannot be undone."' in html
    assert html.count("data-confirm=\"Delete capture-") == 10
    more = alice.get("/media/images/more?offset=10")
    assert more.headers["X-Total-Count"] == "12"
    fragment = more.get_data(as_text=True)
    assert fragment.count("<li data-name=") == 2
    assert 'data-confirm="Delete capture-00.jpg? This cannot be undone."' in fragment
    assert 'src="/media/images/capture-00.jpg/thumbnail.jpg"' in fragment
    assert alice.get("/media/images/more?offset=x").status_code == 400
    assert alice.get("/media/secrets/more").status_code == 404
