"""The published methods kincal implements, cited as the product cites them (a leaf module).

kincal speaks of a paper by its authors, year and title, never by a nickname.
"""

GUO2024 = "Guo et al. 2024"
