"""Afferents: transduction models fitted to recordings (Saal, Delhaye et al. 2017) that turn a
receptor site's stimulus, sampled in time, into spike times."""
