# The ctest labels of the test suite, by test name (`ctest -L LABEL` runs only those tests, `-LE LABEL`
# leaves them out):
#   sanitize-skip  left out by the sanitizer gate (scripts/sanitize.sh -LE sanitize-skip, .ci/run): the slowest
#                  statistical tests and the shard/merge bit-identity tests, whose code paths faster tests
#                  run many times under the sanitizers too (docs/records/reliability.md names them);
#   slow           those, and the hostile-input battery and the Python tests (a minute or more each);
#   mpi            the mpirun tests (tests/mpi, microsim_mpi_tests);
#   browser        the experiment report rendered by a real browser (chromium).
# Used twice: CMakeLists.txt labels the tests it names at configure time (microsim_label_tests), and ctest
# labels the tests GoogleTest discovers at build time (labels_discovered.cmake.in, a TEST_INCLUDE_FILES
# script run after the discovered tests are added).

# sanitize-skip: a test whose name (Suite.Test, with the instantiation prefix and parameter of a TEST_P)
# matches one of these regular expressions anywhere.
set(MICROSIM_SANITIZE_SKIP
  [=[QuadricExactAtTheCornersOfItsRange]=]
  [=[SamplersAgainstOracle]=]
  [=[CubatureSecondPass\.Bounded2023]=]
  [=[CorrectSamplerGrid]=]
  [=[Bounded2023AtGrazingTinyAlpha]=]
  [=[VndfBinSums]=]
  [=[ExactQuadricMatchesAnalyticVndf]=]
  [=[ShardMerge\.MergedShards]=]
  [=[MaskingShardMerge\.MergedShards]=]
  [=[AnalyticScatter\.BinsAreIndependentQuadraturesOverTheirBounds]=]
  [=[AlbedoAnalytic\.MatchesTheBinnedCubatureOverOutgoingDirections]=]
  [=[ValidationTallies\.AnyGroupingOfBlocksIsTheSingleRun]=]
  [=[BsdfSamplers\.(CorrectSamplers|EachNegativeControl|EveryNegativeControl|ABugWithout|EachTransportModes)]=]
  [=[DirectionBinner\.VectorPathEqualsScalarReferenceAndBinOf]=]
  [=[AnalyticScatter\.DielectricsLoseEnergy]=]
  [=[StabilitySweep\.CoversEverySamplerAndFunction]=]
  [=[StabilityBound\.FollowsTheFunctionsTrait]=]
  [=[ExperimentCli\.InterruptedThenResumed]=]
  [=[ExperimentResume\.AnInterruptedWalkOfPerOrderLobes]=]
  [=[AnalyticScatter\.SampledMeasurementsPassAtTheStatedLevel]=]
  [=[SmithWalkEval\.MatchesTheBinnedWalkPerOrderAndInTotal]=]
  [=[AlbedoAnalytic\.ErrorEstimateCoversTheErrorMade]=]
  [=[SamplerTraits\.ACopyUnderAnotherName]=]
  [=[BsdfWeights\.ACorrectConductorSampler]=]
  [=[ExperimentCli\.RunMeetsTheTargetsAndAnotherSeedAgrees]=]
  [=[ExperimentHonesty\.FourTimesThePlannedCost]=]
  [=[ExperimentAnalyticScattering\.IsTheWalksOrderOne]=]
  [=[ExperimentShardCli\.TwoAndThreeShards]=]
  [=[ExperimentSplit\.TwoAndThreeRanks]=]
  [=[ExperimentSplitHeightfield\.RanksAndShards]=]
  [=[ExperimentSplitAlbedo\.OnTiles]=]
  [=[AlbedoGrade\.]=]
  [=[BsdfBatteryWorked\.CorrectBsdfs]=]
  [=[AlbedoCliGrade\.]=]
  [=[CheckBsdfCli\.(TheWorkedPluginsPassWhole|APlantedEvalBugIsRejected)]=]
  [=[WalkEvalCheck\.AStochasticEvalsReciprocityAtAGrazingPair]=]
  # Heavy under the sanitizers, each beside a lighter test of its path that stays in the gate (named after it):
  [=[CliValidate\.DielectricDumpsAreTestedWithPdfBsdf]=]         # ExperimentCli.ASpecValidatesBsdfDumps...
  [=[ExperimentCli\.AnInterruptedRunKeepsItsRejection]=]         # ExperimentCli.InterruptedRunWritesWhatWasDone...
  [=[ExperimentSplitHeightfield\.PartsReversedOrACancelled]=]    # ExperimentSplit.PartsOutOfOrder..., .ACancelledRank...
  [=[ExperimentBsdf\.TheWorkedPluginPasses]=]                    # ExperimentCli.ARejectedBsdfPluginFailsTheRun...
  [=[ExperimentSplitValidation\.TwoAndThreeRanks]=]              # ExperimentSplitTileValidation.RanksAndShards...
  [=[TraceCli\.ValidateAgainstTracedOracle]=]                    # TraceCompare.AReferenceThatDeparts..., .SamplesFromFile...
  [=[NdfMatch\.JointTileMeetsTheLobeBins]=]                      # NdfMatch.JointTileIsAnisotropic...
  [=[AlbedoAnisotropic\.SwappingTheRoughnesses]=]                # AlbedoAnisotropic.EqualRoughnesses...
  [=[SmithWalkOrder1\.(BeckmannEquals|NegativeControls)]=]       # SmithWalkOrder1.GgxMirror..., .GgxDielectric...
  [=[MaskingLeak\.EveryAssemblyUpTo85Degrees]=]                  # MaskingLeak's other tests, Assembly.EveryAssembly...
  [=[ExperimentShardCli\.AMissingRepeatedForeign]=]              # ExperimentShardCli.BadShardValues..., ExperimentSplit.PartsOutOfOrder...
  [=[AlbedoCli\.LayoutTableIsWrittenInTheRenderersForms]=]       # AlbedoCli.ABeckmannLayoutTable..., AlbedoLayoutFiles.*
  [=[ExperimentSplit\.ACancelledRankEndsTheRound]=]              # ExperimentSplit.ShardsOfTheFirstRounds..., CliInterrupt.*
  [=[ExperimentCli\.ASpecRejectsBsdfDumpsInTheWrongTransportMode]=] # ExperimentCli.ASpecValidatesBsdfDumpsInTheirTransportMode
  [=[WalkValidationCli\.ACorrectSmithGlassPasses]=]              # WalkValidationCli.FirefliesAreRejectedNamingTheRow
  [=[BsdfWeights\.FirefliesANegativeWeight]=]                    # BsdfWeights.RefusesWhatItCannotTest, DominantValue.*, ExperimentCli.ASpecValidatesBsdfDumps...
  [=[CliInterrupt\.TraceMaskingTableWhileTracing]=]              # CliInterrupt.TraceMaskingTableWhileBuildingSurfaces
  [=[ReportBrowser\.ChromiumRendersTheReport]=]                  # ReportBrowser.ChromiumShowsARejectedRunsVerdictFirst
  [=[WalkEvalCheck\.AStaleHeightIsRejected]=]                    # WalkEvalCheck.TheWalksOwnValuesPass
  [=[CheckBsdfCli\.ARejectedPluginsPageSaysSo]=]                  # CheckBsdfCli.TheHtmlReportIsSelfContained...
  [=[SurfaceScatter\.MirrorBrdfIsReciprocal]=]                   # SurfaceScatter.DielectricBtdfObeysGeneralisedReciprocity
  [=[AlbedoLayouts\.NodesCentresAndInterpolationError]=]         # AlbedoLayouts.ABeckmannTable..., AlbedoCli.ABeckmannLayoutTable... (its grade interpolates)
  [=[AlbedoGlassLayout\.TableReadAsCyclesReadsItMatches]=]       # AlbedoGlassLayout.PublishedTablesReadAsCyclesReadsThem
  [=[RangeEdges\.SmallestAllowedBuilds]=]                        # RangeEdges.LibraryRuleEdgesMeetTheNdfCheckOverSeeds
)
list(JOIN MICROSIM_SANITIZE_SKIP "|" MICROSIM_SANITIZE_SKIP_REGEX)

# COST (ctest runs the costliest first): the tests of 10 s or more in Release or under the sanitizers. ctest
# learns each test's time after a run, but CI runs on a clean clone, where without it these would start
# wherever they are declared and the last of them would run alone on one core at the end.
set(MICROSIM_HEAVY
  [=[BsdfSamplers\.EveryNegativeControl]=]
  [=[BsdfBatteryWorked\.CorrectBsdfs]=]
  [=[ValidateAllShardMerge\.]=]
  [=[AlbedoCli\.Layout]=]
  [=[RunMpi\.]=]
  [=[CheckBsdfCli\.]=]
  [=[CliValidate\.DielectricDumps]=]
  [=[ExperimentShardCli\.AMissing]=]
  [=[ExperimentCli\.(ASpecValidatesBsdfDumps|AnInterruptedRun)]=]
  [=[WalkEvalCheck\.]=]
  [=[WalkValidationCli\.]=]
  [=[ExperimentSplit\.]=]
  [=[ExperimentResume\.AnInterruptedVndfRound]=]
  [=[BsdfSamplers\.EachTransportModes]=]
  [=[SamplersAgainstOracle]=]
)
list(JOIN MICROSIM_HEAVY "|" MICROSIM_HEAVY_REGEX)
set(MICROSIM_BROWSER_REGEX [=[^ReportBrowser\.]=])

# Sets the labels of each test named (slow, sanitize-skip, browser by name; `extra`: labels for all of them).
function(microsim_label_tests extra)
  foreach(test IN LISTS ARGN)
    set(labels ${extra})
    if(test MATCHES "${MICROSIM_SANITIZE_SKIP_REGEX}")
      list(APPEND labels slow sanitize-skip)
    endif()
    if(test MATCHES "${MICROSIM_BROWSER_REGEX}")
      list(APPEND labels browser)
    endif()
    if(labels)
      set_tests_properties("${test}" PROPERTIES LABELS "${labels}")
    endif()
    if(test MATCHES "${MICROSIM_HEAVY_REGEX}")
      set_tests_properties("${test}" PROPERTIES COST 100)
    endif()
  endforeach()
endfunction()
