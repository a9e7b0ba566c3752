import math

import pytest

from taskseq.sim.catalog import OBJECTS
from taskseq.sim.objects import ATTRIBUTE_NAMES, ObjectSpec, attributes_of_box


def test_attributes_of_a_tall_box():
    a = attributes_of_box((0.1, 0.2, 0.4), {"box", "movable"})
    assert a["height"] == 0.4
    assert a["max_wl"] == 0.2 and a["min_wl"] == 0.1
    assert math.isclose(a["volume"], 0.008)
    assert math.isclose(a["min_over_max"], 0.25) and math.isclose(a["median_over_max"], 0.5)
    assert a["box"] == 1 and a["movable"] == 1 and a["cylinder"] == 0 and a["liquid"] == 0


def test_attributes_of_a_flat_wide_box_use_all_three_dimensions():
    # height is the smallest side here: min/max and median/max must see it
    a = attributes_of_box((0.6, 0.3, 0.05), set())
    assert a["max_wl"] == 0.6 and a["min_wl"] == 0.3
    assert math.isclose(a["min_over_max"], 0.05 / 0.6)
    assert math.isclose(a["median_over_max"], 0.5)
    assert math.isclose(a["volume"], 0.009)


def test_object_has_fourteen_attributes_in_paper_order():
    spec = OBJECTS[12]
    assert list(spec.attributes()) == list(ATTRIBUTE_NAMES)
    assert len(ATTRIBUTE_NAMES) == 14


def test_catalog_has_43_objects_each_with_its_own_attributes():
    assert len(OBJECTS) == 43
    assert len({o.id for o in OBJECTS}) == 43
    vectors = {tuple(o.attributes().values()) for o in OBJECTS}
    assert len(vectors) == 43


@pytest.mark.parametrize("size", [(0.1, -0.2, 0.3), (0.1, 0.0, 0.3), (float("nan"), 0.1, 0.1)])
def test_object_rejects_bad_sizes(size):
    with pytest.raises(ValueError, match="size"):
        ObjectSpec("objX", "bad", "item", size)
