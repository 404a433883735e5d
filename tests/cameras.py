"""Sample cameras for every registered model, covering narrow, wide and > 180 degree settings."""

from __future__ import annotations

from fisheyemotion import calib

# TUM VI cam0 (Kannala-Brandt): corners are 115 degrees off-axis.
TUMVI_KB = dict(fx=190.97847715128717, fy=190.97330705212261, cx=254.93170605935475,
                cy=256.8974428996504, k1=0.0034823894022493434, k2=0.0007150348452162257,
                k3=-0.0020532361418706202, k4=0.00020293673591811182, width=512, height=512)



def tumvi_kb(width: int, height: int, f: float) -> calib.KannalaBrandt:
    """The TUM VI lens's distortion on a ``width x height`` sensor with focal length ``f``
    (pixels) and the principal point at the image centre: the tests' and scenes' camera."""
    return calib.KannalaBrandt(**{**TUMVI_KB, "fx": f, "fy": f, "cx": (width - 1) / 2,
                                  "cy": (height - 1) / 2, "width": width, "height": height})


MODEL_SAMPLES: dict[str, list[calib.CameraModel]] = {
    "pinhole": [calib.Pinhole(fx=300, fy=310, cx=319.5, cy=239.5, width=640, height=480)],
    "kannala_brandt": [
        calib.KannalaBrandt(**TUMVI_KB),
        calib.KannalaBrandt(fx=140, fy=140, cx=320, cy=240, width=640, height=480),  # 360 deg
        calib.KannalaBrandt(fx=1133.11191, fy=1133.11191, cx=960, cy=600, k1=-1.152516,
                            k2=2.913204, k3=-2.482336, k4=0.178503, width=1920, height=1200),
    ],
    "double_sphere": [
        calib.DoubleSphere(fx=158.28600034966977, fy=158.2743455478755, cx=254.96116578191653,
                           cy=256.8894394501779, xi=-0.17213086034353243,
                           alpha=0.5931177593944744, width=512, height=512),
        calib.DoubleSphere(fx=317.55, fy=316.17, cx=724.86, cy=546.57, xi=-0.1996,
                           alpha=0.5925, width=1440, height=1080),
        calib.DoubleSphere(fx=200, fy=200, cx=320, cy=240, xi=0.5, alpha=0.3, width=640,
                           height=480),
    ],
    "enhanced_unified": [
        calib.EnhancedUnified(fx=191.14799836282189, fy=191.13150963902818,
                              cx=254.9585771534443, cy=256.88154645599448,
                              alpha=0.6291060881178562, beta=1.0418067381860868, width=512,
                              height=512),
        calib.EnhancedUnified(fx=250, fy=250, cx=320, cy=240, alpha=0.4, beta=1.2, width=640,
                              height=480),
    ],
    "unified": [
        calib.Unified(fx=400, fy=400, cx=320, cy=240, xi=0.8, width=640, height=480),
        calib.Unified(fx=300, fy=300, cx=320, cy=240, xi=1.5, width=640, height=480),
    ],
    "fisheye624": [  # Project Aria Gen2 side SLAM camera (factory calibration), without and with
        # its valid radius
        calib.Fisheye624(f=244.78391135310176, cx=252.66232836491685, cy=256.6758625428585,
                         k0=0.033700017499895374, k1=-0.0356144764687204, k2=0.05016276920856296,
                         k3=-0.06365513840303465, k4=0.024101530347748173,
                         k5=-0.0028219261779819558, p0=-0.001007436351907263,
                         p1=-0.0013828990859600307, s0=0.0018403425685775804,
                         s1=8.515338893522913e-05, s2=0.0009721496384546848,
                         s3=0.0002693679794197647, width=512, height=512),
    ],
    "radial_poly": [
        calib.RadialPoly(k1=339.749, k2=-31.988, k3=48.275, k4=-7.201, cx_offset=3.942,
                         cy_offset=-3.093, aspect_ratio=1.0, width=1280, height=966),
    ],
}

ALL_CAMERAS = [(name, cam) for name, cams in MODEL_SAMPLES.items() for cam in cams]
CAMERA_IDS = [f"{name}-{i}" for name, cams in MODEL_SAMPLES.items() for i in range(len(cams))]
