"""The bottom layer: what every other layer may use and that uses nothing of handeye's: the
exception types (`handeye.base.errors`) and the vocabulary the data, files, options and messages
share (`handeye.base.vocabulary`)."""
