confirm 5
bogus
