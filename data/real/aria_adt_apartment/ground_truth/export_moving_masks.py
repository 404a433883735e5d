"""Write ``moving/<camera>/<frame>.png`` from the ADT ground truth (run once; needs
``projectaria-tools`` and the shared recording's ``segmentations.vrs``).

Each mask is uint8 on the SLAM camera's pixels: 255 where the instance segmentation shows an
object whose ground-truth pose changes over the clip (the wooden spoon and fork the wearer moves),
128 inside the wearer's 2-D box (the skeleton is not in the segmentation: its box is all the
ground truth has of the arm), 0 elsewhere. Usage::

    python export_moving_masks.py ../../../../shared/real/aria_adt_apartment/ground_truth
"""

import csv
import sys
from collections import defaultdict
from pathlib import Path

import cv2
import numpy as np
from projectaria_tools.core import data_provider
from projectaria_tools.core.stream_id import StreamId

SOURCE = Path(sys.argv[1])
HERE = Path(__file__).resolve().parent
CAMERAS = {"camera-slam-left": ("400-2", "1201-1"), "camera-slam-right": ("400-3", "1201-2")}
SKELETON = "6810803442292599"  # skeleton_aria_association.json
MOVED_M = 1e-3  # an object counts as moving when its pose moves more than this between frames

tracks = defaultdict(list)
for row in csv.DictReader(open(SOURCE / "scene_objects.csv")):
    if row["timestamp[ns]"] != "-1":
        tracks[row["object_uid"]].append(
            [float(row[k]) for k in ("t_wo_x[m]", "t_wo_y[m]", "t_wo_z[m]")])
moving = [int(uid) for uid, t in tracks.items()
          if np.linalg.norm(np.diff(np.array(t), axis=0), axis=1).max() > MOVED_M]
boxes = [r for r in csv.DictReader(open(SOURCE / "2d_bounding_box_with_skeleton.csv"))
         if r["object_uid"] == SKELETON]
segmentations = data_provider.create_vrs_data_provider(str(SOURCE / "segmentations.vrs"))
for camera, (seg_stream, box_stream) in CAMERAS.items():
    stamps = [int(r["capture_timestamp_ns_device"])
              for r in csv.DictReader(open(HERE.parent / camera / "timestamps.csv"))]
    out = HERE / "moving" / camera
    out.mkdir(parents=True, exist_ok=True)
    stream = StreamId(seg_stream)
    for i in range(segmentations.get_num_data(stream)):
        image, record = segmentations.get_image_data_by_index(stream, i)
        frame = int(np.argmin([abs(s - record.capture_timestamp_ns) for s in stamps]))
        seg = image.to_numpy_array()
        mask = np.zeros(seg.shape, np.uint8)
        box = min((r for r in boxes if r["stream_id"] == box_stream),
                  key=lambda r: abs(int(r["timestamp[ns]"]) - stamps[frame]))
        mask[int(box["y_min[pixel]"]):int(box["y_max[pixel]"]) + 1,
             int(box["x_min[pixel]"]):int(box["x_max[pixel]"]) + 1] = 128
        mask[np.isin(seg, moving)] = 255
        cv2.imwrite(str(out / f"{frame:06d}.png"), mask)
        print(camera, frame, "moving px", int((mask == 255).sum()), "wearer box px",
              int((mask == 128).sum()))
