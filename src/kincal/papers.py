"""The published methods kincal implements, cited as the product cites them (a leaf module).

kincal speaks of a paper by its authors, year and title, never by a nickname.
"""

GUO2024 = "Guo et al. 2024"
GUO2024_FULL = ('Guo et al. 2024, "Measurement configuration optimization for robot kinematic calibration based on '
                'ill-conditioned parameter separation", Chinese Journal of Scientific Instrument, '
                'DOI 10.19650/j.cnki.cjsi.J2312263')
PUU3_PAPER = "the 3-PUU error-model verification paper"
PUU3_PAPER_FULL = ("the 3-PUU error-model verification paper (an error-model verification method for parallel robots "
                   "based on parameter identification, with PSO identification in joint space)")
