//! Paper 002 (Jakubiak, Nijmeijer & Lefeber), section 2: the chained form
//! of the unicycle and its observers and controllers.
