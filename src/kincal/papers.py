"""The published methods kincal implements, cited as the product cites them (a leaf module).

kincal speaks of a paper by its authors, year and title, never by a nickname.
"""

GUO2024 = "Guo et al. 2024"
GUO2024_TITLE = ("Ill-conditioned parameter separation based optimization of measurement configuration for robot "
                 "kinematic calibration")  # Chinese Journal of Scientific Instrument, DOI 10.19650/j.cnki.cjsi.J2312263
PUU3_2024 = "the 3-PUU paper of 2024"  # its authors are not named in the text kincal follows
PUU3_2024_TITLE = "Error analysis model of parallel robot based on parameters identification"  # Transactions of
# the Chinese Society for Agricultural Machinery 55(7), 2024, DOI 10.6041/j.issn.1000-1298.2024.07.043
