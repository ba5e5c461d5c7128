"""drapebench.keys.check_known: the one check of given keys against the keys something reads."""

import pytest

from drapebench.keys import check_known


def test_an_unknown_key_is_named_with_the_closest_valid_one_and_every_valid_one():
    with pytest.raises(ValueError, match=r"^unknown material key\(s\) \['thicknes'\] \(did you mean 'thickness'\?\); valid: \['dt', 'thickness'\]$"):
        check_known({"thicknes": 1.0}, ("thickness", "dt"), "material key")
    with pytest.raises(ValueError, match=r"^unknown parameter\(s\) \['zzz'\] for motion 'walk'; valid: \['speed'\]$"):
        check_known(["zzz"], ["speed"], "parameter", "for motion 'walk'")
    check_known({"dt": 1.0}, ("thickness", "dt"), "material key")  # known keys pass
    check_known({}, (), "material key")
