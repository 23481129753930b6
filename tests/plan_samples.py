"""Sample ground-station files for the tests of mavctl's file formats: a QGroundControl
plan with every part (mission items, inclusion and exclusion polygons and circles, rally
points), and a comparison of JSON documents to the precision the wire keeps."""
import pytest

HOME = (47.397742, 8.545594)


def qgc_plan():
    lat, lon = HOME
    items = [
        {"autoContinue": True, "command": 22, "doJumpId": 1, "frame": 3,
         "params": [0, 0, 0, None, lat, lon, 10], "type": "SimpleItem"},
        {"autoContinue": True, "command": 16, "doJumpId": 2, "frame": 3,
         "params": [0.5, 2, 0, None, 47.3980001, 8.5460003, 15.25], "type": "SimpleItem"},
        {"autoContinue": True, "command": 178, "doJumpId": 3, "frame": 2,
         "params": [1, 7.5, -1, 0, 0, 0, 0], "type": "SimpleItem"},
        {"autoContinue": True, "command": 16, "doJumpId": 4, "frame": 3,
         "params": [0, 0, 0, None, 47.3985, 8.5455, 20], "type": "SimpleItem"},
        {"autoContinue": True, "command": 21, "doJumpId": 5, "frame": 3,
         "params": [0, 0, 0, None, lat, lon, 0], "type": "SimpleItem"},
    ]
    square = [[47.3970, 8.5440], [47.3990, 8.5440], [47.3990, 8.5470], [47.3970, 8.5470]]
    triangle = [[47.3978, 8.5450], [47.3981, 8.5452], [47.3978, 8.5454]]
    return {
        "fileType": "Plan",
        "geoFence": {
            "circles": [
                {"circle": {"center": [lat, lon], "radius": 400.5}, "inclusion": True, "version": 1},
                {"circle": {"center": [47.3983, 8.5462], "radius": 12}, "inclusion": False, "version": 1},
            ],
            "polygons": [
                {"inclusion": True, "polygon": square, "version": 1},
                {"inclusion": False, "polygon": triangle, "version": 1},
            ],
            "version": 2,
        },
        "groundStation": "QGroundControl",
        "mission": {"cruiseSpeed": 15, "firmwareType": 12, "globalPlanAltitudeMode": 1,
                    "hoverSpeed": 5, "items": items, "plannedHomePosition": [lat, lon, 488],
                    "vehicleType": 2, "version": 2},
        "rallyPoints": {"points": [[47.3975, 8.5449, 30], [47.3988, 8.5466, 45.5]], "version": 2},
        "version": 1,
    }


def same_numbers(a, b):
    """Equal JSON values, numbers to float32/1e-7 degree precision, null == NaN."""
    if isinstance(a, dict):
        assert isinstance(b, dict) and set(a) == set(b), (a, b)
        for k in a:
            same_numbers(a[k], b[k])
    elif isinstance(a, list):
        assert isinstance(b, list) and len(a) == len(b), (a, b)
        for x, y in zip(a, b):
            same_numbers(x, y)
    elif isinstance(a, (int, float)) and not isinstance(a, bool):
        assert b == pytest.approx(a, rel=1e-6, abs=1e-7), (a, b)
    else:
        assert a == b, (a, b)
